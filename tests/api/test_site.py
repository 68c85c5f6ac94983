"""The site map through the API: keep-out zones reject goals (409 with the reason); the
site's obstacles are the fleet's initial obstacles."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import httpx
import pytest
from support import wait_for

from api.app import create_app
from fleet.core.wire import ParkAssignment
from fleet.io.settings import Settings, load_settings
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from tests.api.conftest import add_robot

EXAMPLE = Path(__file__).resolve().parents[2] / "fleet" / "io" / "sites" / "carpark.toml"

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def site_settings() -> Settings:
    return load_settings(site_file=EXAMPLE)


async def _client(settings: Settings, db: Path) -> AsyncIterator[httpx.AsyncClient]:
    store = SqliteTaskStore(db)
    try:
        with FleetService(settings, MemoryBus(), store) as fleet:
            app = create_app(settings, service=fleet, store=store)
            async with (
                app.router.lifespan_context(app),
                httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://t") as c,
            ):
                yield c
    finally:
        store.close()


@pytest.fixture
async def client(site_settings: Settings, tmp_path: Path) -> AsyncIterator[httpx.AsyncClient]:
    async for c in _client(site_settings, tmp_path / "parkfleet.db"):
        yield c


@pytest.fixture
async def client_no_site(tmp_path: Path) -> AsyncIterator[httpx.AsyncClient]:
    async for c in _client(load_settings(), tmp_path / "parkfleet.db"):
        yield c


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
    posts = [o for o in obstacles if o["end"] is None]
    assert {(o["x"], o["y"]) for o in posts} == {(-5, 3), (5, 3), (-5, -3), (5, -3)}
    walls = [(o["x"], o["y"], *o["end"]) for o in obstacles if o["end"] is not None]
    assert len(walls) == 5 and (-11.5, 7.5, 11.5, 7.5) in walls  # the outer wall's edges
    at_wall = await client.post("/tasks", json={"goal": {"x": 0.0, "y": 7.3}})
    assert at_wall.status_code == 409 and "wall segment" in at_wall.json()["detail"]
    assert (await client.get("/config")).json()["yard"] == [-12.0, 12.0, -8.0, 8.0]
    outside = await client.post("/tasks", json={"goal": {"x": 0.0, "y": 9.0}})
    assert outside.status_code == 409  # goal rejected, with the reason
    assert "outside the yard x in [-12, 12], y in [-8, 8] m" in outside.json()["detail"]


async def test_a_bay_is_reserved_by_exactly_one_active_task(client: httpx.AsyncClient) -> None:
    first = await client.post("/tasks", json={"bay": "A3"})
    assert first.status_code == 201, first.text
    task = first.json()
    assert task["bay"] == "A3" and task["goal"] == {"x": -3.0, "y": 6.0, "theta": 1.5708}
    taken = await client.post("/tasks", json={"bay": "A3"})
    assert taken.status_code == 409
    assert taken.json()["detail"] == f"bay A3 is taken by task {task['id']}"
    states = {b["name"]: b for b in (await client.get("/bays")).json()}
    assert states["A3"]["status"] == "reserved" and states["A3"]["task_id"] == task["id"]
    assert states["A4"]["status"] == "free" and states["C1"]["group"] == "charging"
    await client.post(f"/tasks/{task['id']}/cancel")
    assert (await client.post("/tasks", json={"bay": "A3"})).status_code == 201


async def test_a_group_gives_each_task_a_free_bay_until_none_is_left(
    client: httpx.AsyncClient,
) -> None:
    chosen = []
    for _ in range(3):
        created = await client.post("/tasks", json={"bay_group": "charging"})
        assert created.status_code == 201, created.text
        chosen.append(created.json()["bay"])
    assert chosen == ["C1", "C2", "C3"]
    full = await client.post("/tasks", json={"bay_group": "charging"})
    assert full.status_code == 409
    assert full.json()["detail"] == "every bay of group charging is taken"


async def test_unknown_bays_and_groups_are_404_and_ambiguous_bodies_422(
    client: httpx.AsyncClient,
) -> None:
    unknown = await client.post("/tasks", json={"bay": "Z9"})
    assert unknown.status_code == 404 and unknown.json()["detail"] == "bay Z9 not found"
    group = await client.post("/tasks", json={"bay_group": "valet"})
    assert group.status_code == 404 and group.json()["detail"] == "bay group valet not found"
    both = await client.post("/tasks", json={"bay": "A1", "goal": {"x": 0, "y": 0}})
    assert both.status_code == 422 and "exactly one of goal, bay, bay_group" in both.text
    assert (await client.post("/tasks", json={})).status_code == 422
    site = (await client.get("/site")).json()
    assert site["name"] == "example car park" and len(site["bays"]) == 17


async def test_without_a_site_bays_are_404_with_the_reason(
    client_no_site: httpx.AsyncClient,
) -> None:
    missing = await client_no_site.post("/tasks", json={"bay": "A1"})
    assert missing.status_code == 404 and "no site map" in missing.json()["detail"]
    for path in ("/bays", "/site"):
        r = await client_no_site.get(path)
        assert r.status_code == 404, path
        assert r.json() == {"detail": "this fleet has no site map (--site)"}
    paths = (await client_no_site.get("/openapi.json")).json()["paths"]
    assert "404" in paths["/bays"]["get"]["responses"]
    assert "404" in paths["/site"]["get"]["responses"]


#: A site with a wall across the way and a closed room (parkfleet's site file format).
WALLED = """
name = "walled"
[yard]
xmin = -10.0
xmax = 10.0
ymin = -10.0
ymax = 10.0
[[walls]]
name = "across"
points = [[0.0, -1.5], [0.0, 1.5]]
[[walls]]
name = "room"
points = [[4.0, 4.0], [8.0, 4.0], [8.0, 8.0], [4.0, 8.0]]
closed = true
"""


async def test_a_goal_no_route_reaches_is_409_and_a_task_shows_its_route(
    tmp_path: Path,
) -> None:
    site = tmp_path / "walled.toml"
    site.write_text(WALLED)
    settings = load_settings(site_file=site)
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    bus = MemoryBus()
    try:
        with FleetService(settings, bus, store) as fleet:
            app = create_app(settings, service=fleet, store=store)
            async with (
                app.router.lifespan_context(app),
                httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://t") as c,
            ):
                add_robot(bus, "r1", x=-3.0, y=0.0)
                walled_in = await c.post("/tasks", json={"goal": {"x": 6.0, "y": 6.0}})
                assert walled_in.status_code == 409, walled_in.text
                assert walled_in.json()["detail"].startswith("no route to goal (6.00, 6.00)")
                behind = await c.post("/tasks", json={"goal": {"x": 3.0, "y": 0.0}})
                assert behind.status_code == 201, behind.text
                task_id = behind.json()["id"]

                # the ledger moves the task on before the outbox publishes: wait for the send
                def assignments() -> list[ParkAssignment]:
                    return [
                        m
                        for m in bus.sent("r1")
                        if isinstance(m, ParkAssignment) and m.task_id == task_id
                    ]

                wait_for(lambda: bool(assignments()), 60, "the assignment sent to r1")
                shown = (await c.get(f"/tasks/{task_id}")).json()
                route = [(p["x"], p["y"]) for p in shown["route"]]
                assert route, "the wall is in the way: the task goes round it"
                # round one of the wall's ends, keeping clear of it, ending before the goal
                assert max(abs(y) for _, y in route) > 1.5
                assert route[-1] == pytest.approx((2.0, 0.0))  # the pre-bay point, 1 m before
                assert [tuple(p) for p in assignments()[-1].route] == route
    finally:
        store.close()


async def test_zones_list_the_site_maps_and_the_passages_put_obstacles_make(
    client: httpx.AsyncClient, client_no_site: httpx.AsyncClient
) -> None:
    zones = (await client.get("/zones")).json()
    assert [(z["name"], z["found"], z["robot_ids"]) for z in zones] == [("entrance", False, [])]
    in_zone = await client.post("/tasks", json={"goal": {"x": -10.2, "y": 0.0}})
    assert in_zone.status_code == 409
    assert "inside the single-robot zone entrance" in in_zone.json()["detail"]
    assert (await client_no_site.get("/zones")).json() == []
    corridor = [  # two walls 1.2 m apart, 6 m long: too narrow for two robots to pass
        {"x": -3.0, "y": y, "end": [3.0, y], "radius": 0.3, "body": 0.05} for y in (-0.6, 0.6)
    ]
    assert (await client_no_site.put("/obstacles", json=corridor)).status_code == 200
    (passage,) = (await client_no_site.get("/zones")).json()
    assert passage["name"] == "passage-1" and passage["found"] and passage["convoys"]
    xs = [x for x, _ in passage["polygon"]]
    assert min(xs) < -2.5 and max(xs) > 2.5
