"""``/robots``: the fleet's view of every robot; an operator removes a lost one, and takes a
robot out of service or puts it back."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, Response, status

from api.deps import Authorized, ServiceDep
from api.schemas import ErrorOut, RobotOut

router = APIRouter(prefix="/robots", tags=["robots"])

RobotIdPath = Annotated[str, Path(min_length=1, max_length=200)]
_MUTATING: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorOut, "description": "missing or wrong bearer token"},
    404: {"model": ErrorOut, "description": "unknown robot"},
}


@router.get("")
def list_robots(service: ServiceDep) -> list[RobotOut]:
    """Every robot seen, including lost ones (kept as obstacles at their last pose)."""
    return [RobotOut.of(robot) for robot in sorted(service.robots(), key=lambda r: r.robot_id)]


@router.get("/{robot_id}", responses={404: {"model": ErrorOut}})
def get_robot(robot_id: RobotIdPath, service: ServiceDep) -> RobotOut:
    return RobotOut.of(service.robot(robot_id))


@router.delete(
    "/{robot_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    dependencies=[Authorized],
    responses={
        **_MUTATING,
        409: {"model": ErrorOut, "description": "the robot is connected or has a task"},
    },
)
def remove_robot(robot_id: RobotIdPath, service: ServiceDep) -> Response:
    """Forget a lost robot (taken out of the yard): it is no longer an obstacle, and queued
    tasks naming it fail. A robot still connected, or with a task under way, is a 409."""
    service.remove_robot(robot_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/{robot_id}/decommission", dependencies=[Authorized], responses=_MUTATING)
def decommission_robot(robot_id: RobotIdPath, service: ServiceDep) -> RobotOut:
    """Take the robot out of service: no new task, its task under way is requeued, and
    once lost it no longer counts as an obstacle."""
    return RobotOut.of(service.decommission(robot_id))


@router.post("/{robot_id}/commission", dependencies=[Authorized], responses=_MUTATING)
def commission_robot(robot_id: RobotIdPath, service: ServiceDep) -> RobotOut:
    """Put a decommissioned robot back in service."""
    return RobotOut.of(service.commission(robot_id))
