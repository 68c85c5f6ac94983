"""``GET /metrics``: scraped and parsed with prometheus-client's own parser."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families

from api.metrics import FleetMetrics
from fleet.core.tasks import (
    FleetEvent,
    RobotEvent,
    RobotStatus,
    RobotView,
    Task,
    TaskEvent,
    TaskRequest,
    TaskStatus,
)
from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.service.bus import MemoryBus
from fleet.service.stats import PlannerStats
from tests.api.conftest import add_robot

pytestmark = pytest.mark.anyio


def samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Every sample of an exposition: (name, sorted labels) -> value."""
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(text)
        for s in family.samples
    }


async def scrape(client: httpx.AsyncClient) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    response = await client.get("/metrics")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/plain; version=")
    return samples(response.text)


async def test_metrics_count_tasks_robots_and_estops(
    client: httpx.AsyncClient, bus: MemoryBus
) -> None:
    before = await scrape(client)
    assert before[("parkfleet_tasks", (("status", "queued"),))] == 0
    assert before[("parkfleet_min_separation_meters", ())] == math.inf

    add_robot(bus, "r1", 0.0, 0.0)
    add_robot(bus, "r2", 0.5, 0.0)
    first = (await client.post("/tasks", json={"goal": {"x": 4.0, "y": 4.0}})).json()
    await client.post("/tasks", json={"goal": {"x": -4.0, "y": 4.0}})
    await client.post(f"/tasks/{first['id']}/cancel")
    bus.deliver_state(
        RobotState(
            robot_id="r2", seq=5, stamp=time.time(), pose=Pose(x=0.5, y=0.0), mode=RobotMode.ESTOP
        )
    )
    after = await scrape(client)
    assert after[("parkfleet_tasks_finished_total", (("status", "cancelled"),))] == 1
    assert after[("parkfleet_task_duration_seconds_count", (("status", "cancelled"),))] == 1
    active = sum(
        after[("parkfleet_tasks", (("status", s.value),))] for s in TaskStatus if not s.final
    )
    assert active == 1
    assert after[("parkfleet_robots", (("mode", "estop"),))] == 1
    assert after[("parkfleet_robots", (("mode", "lost"),))] == 0
    assert after[("parkfleet_robot_estops_total", ())] == 1
    assert after[("parkfleet_min_separation_meters", ())] == pytest.approx(0.5)


class FakeSource:
    """A service stand-in with counters as the Zenoh bus reports them."""

    def __init__(self) -> None:
        self.counters = {"bus_dropped_invalid": 3, "bus_dropped_oversized": 1, "plans": 4,
                         "plan_us": 500_000, "recoveries": 2, "replans": 7}  # fmt: skip
        self.listeners: list[Callable[[FleetEvent], None]] = []

    def robots(self) -> list[RobotView]:
        return []

    def tasks(self, status: TaskStatus | None = None, robot_id: str | None = None) -> list[Task]:
        return []

    def add_listener(self, listener: Callable[[FleetEvent], None]) -> Callable[[], None]:
        self.listeners.append(listener)
        return lambda: self.listeners.remove(listener)

    def planner_stats(self) -> PlannerStats:
        return PlannerStats(4, 4, 12.0, 80.0, 0, 0, 0, 0, 0)


def test_service_counters_become_labelled_counters() -> None:
    source = FakeSource()
    metrics = FleetMetrics(source)
    got = samples(metrics.exposition().decode())
    assert got[("parkfleet_messages_dropped_total", (("reason", "invalid"),))] == 3
    assert got[("parkfleet_messages_dropped_total", (("reason", "oversized"),))] == 1
    assert got[("parkfleet_plans_total", ())] == 4
    assert got[("parkfleet_planning_seconds_total", ())] == 0.5
    assert got[("parkfleet_planning_latency_seconds", (("quantile", "0.5"),))] == 0.012
    assert got[("parkfleet_planning_latency_seconds", (("quantile", "0.99"),))] == 0.08
    assert got[("parkfleet_recoveries_total", ())] == 2
    assert got[("parkfleet_service_events_total", (("event", "replans"),))] == 7
    view = RobotView(robot_id="x", status=RobotStatus.LOST, pose=Pose(x=0, y=0), last_seen=0)
    source.listeners[0](RobotEvent(robot=view))  # a lost robot's stale pose is not tracked
    metrics.close()
    assert source.listeners == []


def test_task_events_out_of_order_keep_the_newest_status() -> None:
    """Events come from several service threads: an older one may arrive last."""
    source = FakeSource()
    metrics = FleetMetrics(source)
    request = TaskRequest(goal=Pose(x=1, y=1))
    base = Task(id="t", request=request, created_at=0.0, updated_at=1.0)
    driving = base.model_copy(update={"status": TaskStatus.DRIVING, "updated_at": 2.0})
    assigned = base.model_copy(update={"status": TaskStatus.ASSIGNED, "updated_at": 1.5})
    done = base.model_copy(update={"status": TaskStatus.SUCCEEDED, "updated_at": 3.0})
    for task in (driving, assigned):
        source.listeners[0](TaskEvent(task=task))
    got = samples(metrics.exposition().decode())
    assert got[("parkfleet_tasks", (("status", "driving"),))] == 1
    assert got[("parkfleet_tasks", (("status", "assigned"),))] == 0
    for task in (done, assigned):  # a late copy after the end does not bring it back
        source.listeners[0](TaskEvent(task=task))
    got = samples(metrics.exposition().decode())
    assert (
        sum(got[("parkfleet_tasks", (("status", s.value),))] for s in TaskStatus if not s.final)
        == 0
    )
    assert got[("parkfleet_task_duration_seconds_sum", (("status", "succeeded"),))] == 3.0
