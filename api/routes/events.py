"""``/events``: Server-Sent Events of robot states and task changes (``api.streaming``)."""

from __future__ import annotations

from fastapi import APIRouter, Request, status

from api.deps import ServiceDep
from api.errors import retry_later
from api.schemas import ErrorOut
from api.streaming import EventHub, EventStreamResponse, TooManyClients

router = APIRouter(tags=["events"])

#: Seconds a client turned away (503) is asked to wait before it tries again.
RETRY_AFTER_S = 5


@router.get(
    "/events",
    response_class=EventStreamResponse,
    status_code=status.HTTP_200_OK,
    responses={
        200: {
            "content": {"text/event-stream": {}},
            "description": "`event: robot` (RobotOut, at most 10 Hz per robot) and "
            "`event: task` (TaskOut) frames; a snapshot of every robot first; "
            "`event: overflow` last when the client fell too far behind",
        },
        503: {"model": ErrorOut, "description": "too many open event streams"},
    },
)
async def events(request: Request, service: ServiceDep) -> EventStreamResponse:
    hub: EventHub = request.app.state.events
    client = f"{request.client.host}:{request.client.port}" if request.client else "unknown"
    try:
        stream = hub.subscribe(service, client)
    except TooManyClients as exc:
        raise retry_later(status.HTTP_503_SERVICE_UNAVAILABLE, str(exc), RETRY_AFTER_S) from None
    return EventStreamResponse(stream)
