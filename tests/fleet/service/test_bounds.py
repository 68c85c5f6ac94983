"""Everything the service keeps has a bound, and every deadline runs on the monotonic clock.

Each test here fails without the bound it names: lost robots retained for a while then
removed (or removed by an operator), everything kept per robot going with it, finished
tasks deleted from the store after their retention, recorded paths capped.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from fleet.core.tasks import GoalRejected, RobotConflict, RobotNotFound, TaskStatus
from fleet.core.wire import RobotMode
from fleet.service.fleet_service import RESEND_INTERVAL_S, ROBOT_EVENT_INTERVAL_S
from fleet.service.paths import PATH_SAMPLES_PER_TASK
from tests.fleet.service.conftest import Fleet, ScriptedPlanner, assign_queued, req

DAY = 86400.0


@pytest.fixture
def yard() -> Iterator[Fleet]:
    f = Fleet(
        planner=ScriptedPlanner(assign_queued()),
        task_timeout_s=30.0,
        lost_robot_retention_s=600.0,
        finished_task_retention_s=7 * DAY,
    )
    yield f
    f.service.close()


def test_lost_robots_are_forgotten_after_the_retention_time(yard: Fleet) -> None:
    empty = yard.service.sizes()
    for k in range(50):  # robots that come, work, and die for good
        rid = f"r{k}"
        yard.join(rid, float(k % 10), float(k // 10))
        yard.robot(rid, float(k % 10), float(k // 10), mode=RobotMode.ARRIVED)
        yard.bus.robot_gone(rid)
    assert len(yard.service.robots()) == 50
    assert yard.service.sizes()["parked_robots"] == 50
    yard.clock.advance(599.0)
    yard.service.tick()
    assert len(yard.service.robots()) == 50  # still obstacles where they died
    with pytest.raises(GoalRejected, match="lost robot r0"):
        yard.service.submit(req(0.2, 0.0))
    yard.clock.advance(1.0)
    yard.service.tick()
    assert yard.service.robots() == []
    assert yard.service.sizes() == empty  # nothing per robot is left behind
    assert yard.service.counters["robots_expired"] == 50
    yard.service.submit(req(0.2, 0.0))  # no longer in the way


def test_an_operator_removes_a_lost_robot_but_not_a_connected_or_busy_one(yard: Fleet) -> None:
    with pytest.raises(RobotNotFound):
        yard.service.remove_robot("ghost")
    yard.join("r1", 0.0, 0.0)
    with pytest.raises(RobotConflict, match="connected"):
        yard.service.remove_robot("r1")

    # A robot that never had a liveliness token, with a task under way: not removable.
    yard.robot("r2", 5.0, 0.0)
    busy = yard.service.submit(req(5.0, 3.0, robot="r2"))
    yard.service.tick()
    assert yard.service.task(busy.id).status is TaskStatus.ASSIGNED
    with pytest.raises(RobotConflict, match=f"task {busy.id}"):
        yard.service.remove_robot("r2")

    yard.bus.robot_gone("r1")
    named = yard.service.submit(req(-3.0, 0.0, robot="r1"))  # waits for r1 to come back
    yard.service.remove_robot("r1")
    assert "r1" not in {r.robot_id for r in yard.service.robots()}
    failed = yard.service.task(named.id)
    assert failed.status is TaskStatus.FAILED and "removed" in (failed.reason or "")
    yard.service.submit(req(0.3, 0.0))  # its spot is free
    with pytest.raises(RobotNotFound):
        yard.service.remove_robot("r1")


def test_finished_tasks_leave_the_store_after_their_retention(yard: Fleet) -> None:
    yard.join("r1", 0.0, 0.0)
    old = yard.service.submit(req(3.0, 0.0))
    yard.service.tick()
    yard.robot("r1", 3.0, 0.0, mode=RobotMode.ARRIVED, task_id=old.id)
    assert yard.service.task(old.id).status is TaskStatus.SUCCEEDED
    yard.bus.robot_gone("r1")  # no robot left: the next task stays queued
    queued = yard.service.submit(req(-3.0, 0.0))
    yard.clock.advance(6 * DAY)
    recent = yard.service.submit(req(0.0, 5.0))
    yard.service.cancel(recent.id)
    yard.service.tick()
    assert yard.store.get(old.id) is not None  # 6 days: kept
    yard.clock.advance(1 * DAY + 1.0)
    yard.service.tick()
    assert yard.store.get(old.id) is None and yard.store.history(old.id) == []
    assert yard.store.get(recent.id) is not None  # finished a day ago
    assert yard.store.get(queued.id) is not None  # never finished: never purged
    assert yard.service.counters["tasks_purged"] == 1


def test_a_long_task_path_is_downsampled_to_its_bound(yard: Fleet) -> None:
    yard.join("r1", 0.0, 0.0)
    task = yard.service.submit(req(9.0, 0.0))
    yard.service.tick()
    for k in range(5 * PATH_SAMPLES_PER_TASK):
        yard.clock.advance(0.02)
        yard.robot("r1", k * 1e-3, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    path = yard.service.path(task.id)
    assert PATH_SAMPLES_PER_TASK / 4 <= len(path) <= PATH_SAMPLES_PER_TASK + 1
    assert path[0][1] == 0.0 and path[-1][1] == pytest.approx(
        (5 * PATH_SAMPLES_PER_TASK - 1) * 1e-3
    )
    assert yard.service.sizes()["path_samples"] <= PATH_SAMPLES_PER_TASK


def test_a_wall_clock_step_moves_no_deadline(yard: Fleet) -> None:
    """Timeouts, re-sends, event throttling and retention run on the monotonic clock; the
    wall clock only stamps what is stored and shown."""
    yard.join("r1", 0.0, 0.0)
    task = yard.service.submit(req(3.0, 0.0))
    yard.service.tick()
    assert len(yard.parks("r1")) == 1
    yard.bus.robot_alive("r9")
    yard.robot("r9", 8.0, 8.0)
    yard.bus.robot_gone("r9")

    yard.clock.step_wall(+2 * DAY)  # NTP or an operator sets the clock forward
    yard.service.tick()
    assert yard.service.task(task.id).status is TaskStatus.ASSIGNED  # no timeout
    assert len(yard.parks("r1")) == 1  # no early re-send
    assert "r9" in {r.robot_id for r in yard.service.robots()}  # retention unaffected

    yard.clock.step_wall(-4 * DAY)  # ... and back, past where it started
    yard.clock.advance(RESEND_INTERVAL_S)
    yard.service.tick()
    assert len(yard.parks("r1")) == 2  # the re-send is not stalled
    events = len(yard.events)
    yard.clock.advance(ROBOT_EVENT_INTERVAL_S)
    yard.robot("r1", 0.1, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    assert len(yard.events) > events  # robot events are not throttled for days
    yard.clock.advance(30.0)
    yard.service.tick()
    failed = yard.service.task(task.id)
    assert failed.status is TaskStatus.FAILED  # the timeout comes on time
    assert failed.updated_at == pytest.approx(yard.clock.wall())  # stamped on the wall clock
