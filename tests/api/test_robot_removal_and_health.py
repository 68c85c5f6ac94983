"""DELETE /robots/{id} (an operator forgets a lost robot) and the service's figures in
/healthz (planning latency, fallbacks, drops, sizes of the bounded structures)."""

from __future__ import annotations

import httpx
import pytest
from support import wait_for

from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from tests.api.conftest import TOKEN, add_robot

pytestmark = pytest.mark.anyio


async def test_a_lost_robot_can_be_removed_once(
    client: httpx.AsyncClient, bus: MemoryBus, fleet: FleetService
) -> None:
    r = await client.delete("/robots/ghost")
    assert r.status_code == 404 and "ghost" in r.json()["detail"]

    add_robot(bus, "r1", x=2.0, y=2.0)
    r = await client.delete("/robots/r1")
    assert r.status_code == 409
    assert "connected" in r.json()["detail"]  # the reason, not just a code

    bus.robot_gone("r1")
    assert (await client.get("/robots/r1")).json()["status"] == "lost"
    blocked = await client.post("/tasks", json={"goal": {"x": 2.3, "y": 2.0}})
    assert blocked.status_code == 409 and "lost robot r1" in blocked.json()["detail"]
    r = await client.delete("/robots/r1")
    assert r.status_code == 204 and r.content == b""
    assert (await client.get("/robots/r1")).status_code == 404
    assert (await client.get("/robots")).json() == []
    assert (await client.post("/tasks", json={"goal": {"x": 2.3, "y": 2.0}})).status_code == 201
    assert (await client.delete("/robots/r1")).status_code == 404


async def test_removing_a_robot_needs_the_token(
    auth_client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    add_robot(bus, "r1")
    bus.robot_gone("r1")
    r = await auth_client.delete("/robots/r1")
    assert r.status_code == 401 and r.headers["WWW-Authenticate"] == "Bearer"
    r = await auth_client.delete("/robots/r1", headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 204


async def test_healthz_shows_planning_and_sizes(
    client: httpx.AsyncClient, bus: MemoryBus, fleet: FleetService
) -> None:
    body = (await client.get("/healthz")).json()
    planner = body["planner"]
    assert planner["plans"] == 0 and planner["p50_ms"] is None and planner["p99_ms"] is None
    assert {"fallbacks", "rebased", "stale_dropped", "unsafe_dropped"} <= set(planner)
    assert body["sizes"]["robots"] == 0 and body["sizes"]["tasks_active"] == 0

    add_robot(bus, "r1")
    created = await client.post("/tasks", json={"goal": {"x": 3.0, "y": 0.0}, "direction": "cw"})
    assert created.status_code == 201
    wait_for(lambda: fleet.planner_stats().plans >= 1, 60, "a plan")
    body = (await client.get("/healthz")).json()
    assert body["planner"]["plans"] >= 1 and body["planner"]["window"] >= 1
    assert body["planner"]["p50_ms"] > 0 and body["planner"]["p99_ms"] >= body["planner"]["p50_ms"]
    assert body["sizes"]["robots"] == 1 and body["sizes"]["tasks_active"] == 1
    assert body["counters"]["plans"] >= 1
