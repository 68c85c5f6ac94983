"""The site map through the API: keep-out zones reject goals (409 with the reason); the
site's obstacles are the fleet's initial obstacles."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import httpx
import pytest

from api.app import create_app
from fleet.io.settings import Settings, load_settings
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore

EXAMPLE = Path(__file__).resolve().parents[2] / "fleet" / "io" / "sites" / "carpark.toml"

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def site_settings() -> Settings:
    return load_settings(site_file=EXAMPLE)


@pytest.fixture
async def client(site_settings: Settings, tmp_path: Path) -> AsyncIterator[httpx.AsyncClient]:
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    try:
        with FleetService(site_settings, MemoryBus(), store) as fleet:
            app = create_app(site_settings, service=fleet)
            async with (
                app.router.lifespan_context(app),
                httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://t") as c,
            ):
                yield c
    finally:
        store.close()


async def test_goals_in_keep_out_zones_are_409_with_the_zone_named(
    client: httpx.AsyncClient,
) -> None:
    inside = await client.post("/tasks", json={"goal": {"x": -11.0, "y": 0.0}})
    assert inside.status_code == 409
    assert inside.json()["detail"] == "goal (-11.00, 0.00) lies inside keep-out zone ramp"
    near = await client.post("/tasks", json={"goal": {"x": 8.0, "y": -3.9}})
    assert near.status_code == 409 and "from keep-out zone hydrant" in near.json()["detail"]
    ok = await client.post("/tasks", json={"goal": {"x": 0.0, "y": 0.0}})
    assert ok.status_code == 201, ok.text


async def test_the_site_sets_the_yard_and_the_initial_obstacles(client: httpx.AsyncClient) -> None:
    obstacles = (await client.get("/obstacles")).json()
    assert {(o["x"], o["y"]) for o in obstacles} == {(-5, 3), (5, 3), (-5, -3), (5, -3)}
    assert (await client.get("/config")).json()["yard"] == [-12.0, 12.0, -8.0, 8.0]
    outside = await client.post("/tasks", json={"goal": {"x": 0.0, "y": 9.0}})
    assert outside.status_code == 422
