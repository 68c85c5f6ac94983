"""``/site`` and ``/bays``: the site map (yard, obstacles, keep-out zones, bays) and the
state of every bay (free, reserved by an active task, occupied by a parked robot)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, status

from api.deps import ServiceDep, SettingsDep
from api.schemas import BayOut, ErrorOut
from fleet.core.site import Site

router = APIRouter(tags=["site"])


@router.get("/site", responses={404: {"model": ErrorOut, "description": "no site map"}})
async def site(settings: SettingsDep) -> Site:
    """The site map the fleet runs with (``--site`` / ``PARKFLEET_SITE_FILE``)."""
    if settings.site is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "this fleet has no site map (--site)")
    return settings.site


@router.get("/bays")
def bays(service: ServiceDep) -> list[BayOut]:
    """Every bay with its state; empty without a site map."""
    return [BayOut.of(state) for state in service.bays()]
