"""The operator dashboard: ``/`` (the page), ``/static/<file>`` (its assets) and ``/config``.

The page is plain HTML, CSS and ES modules in ``api/static`` (no build step). Assets are
served from a fixed list of the files shipped in that folder, so no request path ever
reaches the file system. ``/config`` tells the page what it cannot learn elsewhere: the
yard, the robot and peer influence radii, and whether mutating calls need a token.
"""

from __future__ import annotations

import mimetypes
from pathlib import Path

from fastapi import APIRouter, HTTPException, status
from fastapi.responses import FileResponse
from pydantic import BaseModel, Field

from api.deps import SettingsDep

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"

#: Files the dashboard may serve, by name (computed once: the folder ships with the package).
ASSETS: dict[str, Path] = (
    {p.name: p for p in STATIC_DIR.iterdir() if p.is_file()} if STATIC_DIR.is_dir() else {}
)

#: The browser revalidates every load (cheap: ETag / Last-Modified), so an upgraded server
#: never runs with a stale script.
_REVALIDATE = {"Cache-Control": "no-cache"}

_MEDIA_TYPES = {".js": "text/javascript", ".css": "text/css", ".html": "text/html"}

router = APIRouter(tags=["dashboard"])


class DashboardConfigOut(BaseModel):
    """What the dashboard needs to draw the yard and talk to the API."""

    fleet_name: str
    yard: tuple[float, float, float, float] = Field(description="xmin, xmax, ymin, ymax [m]")
    robot_radius: float = Field(
        description="host profile's body radius [m] (undescribed robots; others: their radius)"
    )
    peer_radius: float = Field(description="influence radius of a peer robot, Eq. (27) [m]")
    auth: bool = Field(description="POST/PUT need 'Authorization: Bearer <token>'")
    site: bool = Field(default=False, description="a site map is loaded (GET /site, /bays)")


def _asset(name: str) -> FileResponse:
    path = ASSETS.get(name)
    if path is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no such asset: {name}")
    media_type = _MEDIA_TYPES.get(path.suffix) or mimetypes.guess_type(path.name)[0]
    return FileResponse(path, media_type=media_type, headers=_REVALIDATE)


@router.get("/", include_in_schema=False)
async def index() -> FileResponse:
    """The dashboard page."""
    return _asset("index.html")


@router.get("/static/{name}", include_in_schema=False)
async def static_asset(name: str) -> FileResponse:
    return _asset(name)


@router.get("/config")
async def dashboard_config(settings: SettingsDep) -> DashboardConfigOut:
    return DashboardConfigOut(
        fleet_name=settings.fleet_name,
        yard=settings.yard,
        robot_radius=settings.profile.radius,
        peer_radius=settings.avoidance.peer_radius,
        auth=settings.api_token is not None,
        site=settings.site is not None,
    )
