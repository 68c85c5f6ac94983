"""``GET /tasks/{id}/events``: every stored transition of a task."""

from __future__ import annotations

import time

import httpx
import pytest
from support import wait_for

from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from tests.api.conftest import add_robot

pytestmark = pytest.mark.anyio


async def test_history_lists_every_transition_with_robot_law_and_reason(
    client: httpx.AsyncClient, bus: MemoryBus, fleet: FleetService
) -> None:
    add_robot(bus, "r1")
    task = (
        await client.post("/tasks", json={"goal": {"x": 3.0, "y": 0.0}, "direction": "cw"})
    ).json()
    wait_for(lambda: fleet.task(task["id"]).status.value == "assigned", 10, "assignment")
    bus.deliver_state(
        RobotState(robot_id="r1", seq=1, stamp=time.time(), pose=Pose(x=0.1, y=0.0),
                   mode=RobotMode.DRIVING, task_id=task["id"])
    )  # fmt: skip
    await client.post(f"/tasks/{task['id']}/cancel")
    events = (await client.get(f"/tasks/{task['id']}/events")).json()
    assert [(e["event"], e["status"]) for e in events] == [
        ("created", "queued"),
        ("assigned", "assigned"),
        ("acknowledged", "driving"),
        ("cancelled", "cancelled"),
    ]
    assert events[1]["robot_id"] == "r1" and events[1]["law"] == "cw"
    assert events[1]["attempts"] == 1 and events[1]["revision"] == 0
    assert events[-1]["reason"] == "cancelled by request"
    assert [e["at"] for e in events] == sorted(e["at"] for e in events)


async def test_history_of_an_unknown_task_is_404(client: httpx.AsyncClient) -> None:
    missing = await client.get("/tasks/nope/events")
    assert missing.status_code == 404 and missing.json()["detail"] == "task nope not found"
