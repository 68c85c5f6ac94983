"""``/events``: Server-Sent Events of robot states and task changes."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse

from api.deps import ServiceDep
from api.streaming import EventHub

router = APIRouter(tags=["events"])


@router.get(
    "/events",
    response_class=StreamingResponse,
    responses={
        200: {
            "content": {"text/event-stream": {}},
            "description": "`event: robot` (RobotOut, at most 10 Hz per robot) and "
            "`event: task` (TaskOut) frames; a snapshot of every robot first",
        }
    },
)
async def events(request: Request, service: ServiceDep) -> StreamingResponse:
    hub: EventHub = request.app.state.events
    return StreamingResponse(
        hub.stream(service),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )
