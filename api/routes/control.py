"""``/control``: pause, resume, e-stop and release the fleet or one robot (VDA 5050's
``startPause`` / ``stopPause`` and emergency stop).

The fleet service publishes the command on the Zenoh control key every agent obeys
(``fleet.core.wire``), holds the robots' tasks (no timeout, no new task) and re-sends an
e-stop or a pause to a robot that does not report obeying it. The same commands work
without the service: ``parkfleet estop | pause | resume``.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Path

from api.deps import Authorized, ServiceDep
from api.schemas import ControlIn, ControlOut, ControlStateOut, ErrorOut, HoldOut
from fleet.core.wire import ControlAction

router = APIRouter(prefix="/control", tags=["control"])

_ACTION_DOC = (
    "pause: robots stop and keep their tasks; resume: they drive on; estop: wheels to zero "
    "at once, latched until release; release: clears the e-stop (a paused robot stays paused)"
)


@router.post(
    "/{action}",
    dependencies=[Authorized],
    responses={
        401: {"model": ErrorOut, "description": "missing or wrong bearer token"},
        404: {"model": ErrorOut, "description": "unknown robot"},
    },
)
def control(
    action: Annotated[ControlAction, Path(description=_ACTION_DOC)],
    service: ServiceDep,
    body: Annotated[ControlIn | None, Body()] = None,
) -> ControlOut:
    """Send an operator command to the whole fleet, or to ``robot_id``."""
    request = body or ControlIn()
    return ControlOut.of(service.control(action, request.robot_id, request.reason))


@router.get("")
def control_state(service: ServiceDep) -> ControlStateOut:
    """What the operator asked: the fleet-wide hold, and robots with a command of their own."""
    state = service.control_state()
    fleet = state.fleet
    return ControlStateOut(
        fleet=HoldOut(paused=fleet.paused, estop=fleet.estop),
        robots={rid: HoldOut(paused=h.paused, estop=h.estop) for rid, h in state.robots.items()},
    )
