"""``/obstacles``: the yard's static obstacles (replaced whole by PUT)."""

from __future__ import annotations

from fastapi import APIRouter

from api.deps import Authorized, ObstaclesBody, ServiceDep
from api.schemas import ErrorOut, ObstacleOut

router = APIRouter(prefix="/obstacles", tags=["obstacles"])


@router.get("")
def list_obstacles(service: ServiceDep) -> list[ObstacleOut]:
    return [ObstacleOut.of(o) for o in service.obstacles()]


@router.put("", dependencies=[Authorized], responses={401: {"model": ErrorOut}})
def replace_obstacles(body: ObstaclesBody, service: ServiceDep) -> list[ObstacleOut]:
    """Replace every static obstacle; robots receive the new set over Zenoh."""
    service.set_obstacles([o.to_obstacle() for o in body])
    return [ObstacleOut.of(o) for o in service.obstacles()]
