"""The planner in its own process: the same plans, restarted when it dies, gone when closed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import is_alive, read_line, wait_for

import fleet
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


#: A process that opens a planner process, says its worker's id and waits for stdin to end.
_HOLDER = """
import sys
from fleet.core.planner import plan
from fleet.service.planner_process import PlannerProcess
planner = PlannerProcess(plan)
print(planner.pid, flush=True)
sys.stdin.read()
"""


def test_the_planner_process_ends_when_the_process_that_opened_it_is_sigkilled() -> None:
    # A SIGKILLed service runs no clean-up: its planner worker must notice on its own. It
    # holds the write end of its own call queue (a pickled multiprocessing Queue carries
    # both ends), so it never reads EOF there; left alone it lived on as an orphan forever,
    # holding the dead service's stdout (a test reading that pipe to EOF hung).
    root = str(Path(fleet.__file__).resolve().parents[1])
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLDER],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": root},
    )
    worker = 0
    try:
        worker = int(read_line(holder, 120))
        assert is_alive(worker)
        holder.kill()
        holder.wait()
        wait_for(lambda: not is_alive(worker), 60, "the orphaned planner worker to end")
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
        if worker and is_alive(worker):
            os.kill(worker, signal.SIGKILL)
        for pipe in (holder.stdin, holder.stdout):
            if pipe is not None:
                pipe.close()
