"""``/healthz``: liveness, and a few numbers worth a glance."""

from __future__ import annotations

from fastapi import APIRouter, Request

from api.deps import ServiceDep, SettingsDep
from api.schemas import HealthOut, PlannerOut

router = APIRouter(tags=["health"])


@router.get("/healthz")
async def healthz(request: Request, service: ServiceDep, settings: SettingsDep) -> HealthOut:
    # async: reads only in-memory state, so no thread-pool hop.
    return HealthOut(
        robots=len(service.robots()),
        yard=settings.yard,
        zenoh=list(getattr(request.app.state, "zenoh_locators", [])),
        auth=settings.api_token is not None,
        counters=dict(service.counters),
        planner=PlannerOut.of(service.planner_stats()),
        sizes=service.sizes(),
    )
