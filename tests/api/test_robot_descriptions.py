"""/robots shows what each robot says it is; a robot that may not reverse gets no task."""

from __future__ import annotations

import httpx
import pytest

from fleet.core.params import RobotProfile
from fleet.core.wire import RobotDescription
from fleet.service.bus import MemoryBus
from tests.api.conftest import add_robot

pytestmark = pytest.mark.anyio

TURTLEBOT = RobotProfile(wheel_radius=0.036, half_axle=0.117, max_wheel_speed=8.5, radius=0.17)


async def test_robots_show_described_profiles_and_the_host_fallback(
    client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    add_robot(bus, "tb4", 0.0, 0.0)
    add_robot(bus, "old", 0.0, 3.0)
    bus.deliver_description(RobotDescription.of("tb4", TURTLEBOT, model="TurtleBot 4"))
    tb4 = (await client.get("/robots/tb4")).json()
    assert tb4["described"] is True and tb4["model"] == "TurtleBot 4"
    assert tb4["radius"] == pytest.approx(0.17)
    assert tb4["max_wheel_speed"] == pytest.approx(8.5)
    assert tb4["max_speed"] == pytest.approx(0.306)
    assert tb4["may_reverse"] is True
    old = {r["robot_id"]: r for r in (await client.get("/robots")).json()}["old"]
    assert old["described"] is False and old["model"] is None and old["max_speed"] is None


async def test_a_task_for_a_robot_that_may_not_reverse_is_a_409_with_the_reason(
    client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    add_robot(bus, "fwd", 0.0, 0.0)
    bus.deliver_description(RobotDescription.of("fwd", RobotProfile(), may_reverse=False))
    r = await client.post("/tasks", json={"goal": {"x": 3.0, "y": 0.0}, "robot_id": "fwd"})
    assert r.status_code == 409
    assert "may not reverse" in r.text
    assert (await client.get("/robots/fwd")).json()["may_reverse"] is False
