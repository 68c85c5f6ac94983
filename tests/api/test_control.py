"""``/control``: operator commands over REST (auth, validation, state)."""

from __future__ import annotations

import httpx
import pytest

from fleet.core.wire import ControlAction
from fleet.service.bus import MemoryBus
from tests.api.conftest import TOKEN, add_robot

pytestmark = pytest.mark.anyio


async def test_estop_and_release_the_fleet_and_pause_one_robot(
    client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    add_robot(bus, "r1")
    stopped = await client.post("/control/estop", json={"reason": "drill"})
    assert stopped.status_code == 200, stopped.text
    body = stopped.json()
    assert body["command"] == "estop" and body["robot_id"] is None and body["reason"] == "drill"
    assert body["issuer"] == "fleet-service"
    assert (await client.get("/control")).json() == {
        "fleet": {"paused": False, "estop": True},
        "robots": {},
    }
    paused = await client.post("/control/pause", json={"robot_id": "r1"})
    assert paused.status_code == 200 and paused.json()["robot_id"] == "r1"
    assert (await client.post("/control/release")).status_code == 200  # no body: the fleet
    assert (await client.get("/control")).json()["robots"] == {}
    assert [(m.command, m.robot_id) for m in bus.controls] == [
        (ControlAction.ESTOP, None),
        (ControlAction.PAUSE, "r1"),
        (ControlAction.RELEASE, None),
    ]


async def test_bad_control_requests_are_4xx_with_the_reason(client: httpx.AsyncClient) -> None:
    unknown = await client.post("/control/pause", json={"robot_id": "ghost"})
    assert unknown.status_code == 404 and unknown.json()["detail"] == "robot ghost not found"
    assert (await client.post("/control/explode")).status_code == 422
    bad_id = await client.post("/control/estop", json={"robot_id": "r*"})
    assert bad_id.status_code == 422 and "robot_id" in bad_id.json()["detail"]


async def test_control_needs_the_token_when_one_is_set(
    auth_client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    assert (await auth_client.post("/control/estop")).status_code == 401
    assert bus.controls == []
    ok = await auth_client.post("/control/estop", headers={"Authorization": f"Bearer {TOKEN}"})
    assert ok.status_code == 200
    assert (await auth_client.get("/control")).status_code == 200  # reads stay open


async def test_decommission_and_commission_over_rest(
    auth_client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    add_robot(bus, "r1")
    headers = {"Authorization": f"Bearer {TOKEN}"}
    assert (await auth_client.post("/robots/r1/decommission")).status_code == 401
    out = await auth_client.post("/robots/r1/decommission", headers=headers)
    assert out.status_code == 200 and out.json()["in_service"] is False
    assert (await auth_client.get("/robots/r1")).json()["in_service"] is False
    named = await auth_client.post(
        "/tasks", json={"goal": {"x": 2, "y": 2}, "robot_id": "r1"}, headers=headers
    )
    assert named.status_code == 409 and "decommissioned" in named.json()["detail"]
    back = await auth_client.post("/robots/r1/commission", headers=headers)
    assert back.status_code == 200 and back.json()["in_service"] is True
    missing = await auth_client.post("/robots/ghost/decommission", headers=headers)
    assert missing.status_code == 404
