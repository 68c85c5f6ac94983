"""``/site``, ``/bays`` and ``/zones``: the site map (yard, obstacles, keep-out zones, bays,
single-robot zones), the state of every bay (free, reserved by an active task, occupied by
a parked robot) and who holds each single-robot zone."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, status

from api.deps import ServiceDep, SettingsDep
from api.schemas import BayOut, ErrorOut, ZoneOut
from fleet.core.site import Site
from fleet.io.settings import Settings

router = APIRouter(tags=["site"])


_NO_SITE: dict[int | str, dict[str, Any]] = {404: {"model": ErrorOut, "description": "no site map"}}


def _site_of(settings: Settings) -> Site:
    """The configured site map; 404 when the fleet runs without one."""
    if settings.site is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "this fleet has no site map (--site)")
    return settings.site


@router.get("/site", responses=_NO_SITE)
async def site(settings: SettingsDep) -> Site:
    """The site map the fleet runs with (``--site`` / ``PARKFLEET_SITE_FILE``)."""
    return _site_of(settings)


@router.get("/bays", responses=_NO_SITE)
def bays(service: ServiceDep, settings: SettingsDep) -> list[BayOut]:
    """Every bay of the site map with its state (404 without a site map)."""
    _site_of(settings)
    return [BayOut.of(state) for state in service.bays()]


@router.get("/zones")
def zones(service: ServiceDep) -> list[ZoneOut]:
    """Every single-robot zone -- the site map's and the narrow passages found in the walls
    and posts -- with the robot holding it (empty: none; works without a site map)."""
    return [ZoneOut.of(state) for state in service.zones()]
