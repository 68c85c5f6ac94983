"""``/robots``: the fleet's view of every robot."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path

from api.deps import ServiceDep
from api.schemas import ErrorOut, RobotOut

router = APIRouter(prefix="/robots", tags=["robots"])


@router.get("")
def list_robots(service: ServiceDep) -> list[RobotOut]:
    """Every robot seen, including lost ones (kept as obstacles at their last pose)."""
    return [RobotOut.of(robot) for robot in sorted(service.robots(), key=lambda r: r.robot_id)]


@router.get("/{robot_id}", responses={404: {"model": ErrorOut}})
def get_robot(
    robot_id: Annotated[str, Path(min_length=1, max_length=200)], service: ServiceDep
) -> RobotOut:
    return RobotOut.of(service.robot(robot_id))
