"""The planner in its own process: the same plans, restarted when it dies, gone when closed."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator

import pytest

from fleet.bench.closed_loop import OfflineFleet
from fleet.bench.scenarios import swap
from fleet.core.planner import PlanningSnapshot, plan
from fleet.core.tasks import TaskStatus
from fleet.service.planner_process import PlannerProcess
from fleet.service.stats import Counters
from tests.fleet.service.conftest import Fleet, req


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.fixture
def snapshot() -> PlanningSnapshot:
    fleet = OfflineFleet(swap(4, "right"))
    fleet.submit_arrived()
    return fleet.snapshot().snapshot


@pytest.fixture
def counters() -> Counters:
    return Counters()


@pytest.fixture
def planner(counters: Counters) -> Iterator[PlannerProcess]:
    p = PlannerProcess(plan, counters)
    yield p
    p.close()


def test_it_plans_what_the_planner_plans_in_this_process(
    planner: PlannerProcess, snapshot: PlanningSnapshot
) -> None:
    here = plan(snapshot)
    there = planner(snapshot)
    assert there.decisions == here.decisions and there.safe == here.safe
    assert planner.pid is not None and planner.pid != os.getpid()


def test_a_killed_planner_process_is_restarted_counted_and_the_plan_still_comes(
    planner: PlannerProcess, counters: Counters, snapshot: PlanningSnapshot
) -> None:
    first = planner.pid
    assert first is not None
    os.kill(first, signal.SIGKILL)
    assert planner(snapshot).decisions == plan(snapshot).decisions
    assert counters.get("planner_restarts") == 1
    assert planner.pid not in (None, first)


def test_closing_stops_the_process_and_refuses_plans(snapshot: PlanningSnapshot) -> None:
    planner = PlannerProcess(plan)
    pid = planner.pid
    assert pid is not None and _alive(pid)
    planner.close()
    planner.close()  # idempotent
    assert not _alive(pid)
    with pytest.raises(RuntimeError, match="closed"):
        planner(snapshot)


def test_a_service_planning_in_the_process_counts_its_restarts() -> None:
    process = PlannerProcess(plan)
    fleet = Fleet(planner=process)
    try:
        pid = process.pid
        assert pid is not None
        fleet.join("r1", 0.0, 0.0)
        first = fleet.service.submit(req(3.0, 0.0))
        fleet.service.tick()
        assert fleet.service.task(first.id).status is TaskStatus.ASSIGNED
        os.kill(pid, signal.SIGKILL)
        fleet.join("r2", 0.0, 3.0)
        second = fleet.service.submit(req(-3.0, 3.0))
        fleet.service.tick()
        assert fleet.service.task(second.id).status is TaskStatus.ASSIGNED
        assert fleet.service.counters["planner_restarts"] == 1
    finally:
        fleet.service.close()
        process.close()
    assert not _alive(pid)
