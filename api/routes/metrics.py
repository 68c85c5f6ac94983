"""``/metrics``: Prometheus text format (see :mod:`api.metrics`)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request, Response, status
from prometheus_client import CONTENT_TYPE_LATEST

from api.metrics import FleetMetrics

router = APIRouter(tags=["metrics"])


@router.get(
    "/metrics",
    response_class=Response,
    responses={
        200: {
            "content": {
                CONTENT_TYPE_LATEST: {
                    "example": "# HELP parkfleet_robots Robots by mode\n"
                    "# TYPE parkfleet_robots gauge\n"
                    'parkfleet_robots{mode="driving"} 3.0\n'
                }
            },
            "description": "tasks by status, task durations, planning, robots by mode, "
            "dropped messages, recoveries, e-stops, smallest separation seen",
        }
    },
)
def metrics(request: Request) -> Response:
    collector: FleetMetrics | None = getattr(request.app.state, "metrics", None)
    if collector is None:
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, "fleet service not running")
    return Response(collector.exposition(), media_type=CONTENT_TYPE_LATEST)
