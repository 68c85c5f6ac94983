"""FleetService logic with the in-memory bus and store and a fake clock (no threads)."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from functools import partial

import pytest
from support import wait_for

from fleet.core.planner import PlannerConfig, plan
from fleet.core.tasks import (
    FleetEvent,
    GoalRejected,
    RobotEvent,
    RobotNotFound,
    RobotStatus,
    Task,
    TaskConflict,
    TaskEvent,
    TaskNotFound,
    TaskRequest,
    TaskStatus,
)
from fleet.core.types import Law
from fleet.core.wire import (
    Obstacle,
    ParkAssignment,
    Pose,
    RobotMode,
    RobotState,
)
from fleet.io.settings import Settings
from fleet.paper.scenarios import SCENARIOS
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import RESEND_INTERVAL_S, FleetService
from fleet.service.store import MemoryTaskStore
from robot_agent.logic import apply_assignment
from tests.fleet.service.conftest import Fleet, req


def test_full_life_cycle_is_stored_before_it_is_announced(fleet: Fleet) -> None:
    stored_at_event: list[TaskStatus | None] = []

    def check(event: FleetEvent) -> None:
        if isinstance(event, TaskEvent):
            got = fleet.store.get(event.task.id)
            stored_at_event.append(got.status if got else None)

    fleet.service.add_listener(check)
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    assert task.status == TaskStatus.QUEUED

    fleet.service.tick()
    task = fleet.service.task(task.id)
    assert (
        task.status == TaskStatus.ASSIGNED and task.robot_id == "r1" and task.law in ("cw", "ccw")
    )
    (park,) = fleet.parks("r1")
    assert park.task_id == task.id and park.goal == Pose(x=3.0, y=0.0) and park.law == task.law

    fleet.robot("r1", 0.5, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    assert fleet.service.task(task.id).status == TaskStatus.DRIVING
    fleet.robot("r1", 3.0, 0.0, mode=RobotMode.ARRIVED, task_id=task.id)
    done = fleet.service.task(task.id)
    assert done.status == TaskStatus.SUCCEEDED and done.reason is None

    expected = [TaskStatus.QUEUED, TaskStatus.ASSIGNED, TaskStatus.DRIVING, TaskStatus.SUCCEEDED]
    assert fleet.task_statuses(task.id) == expected
    assert stored_at_event == expected
    assert [ev for _, ev, _ in fleet.store.history(task.id)] == [
        "created",
        "assigned",
        "acknowledged",
        "succeeded",
    ]
    assert fleet.service.robot("r1").status == RobotStatus.ARRIVED
    assert any(isinstance(e, RobotEvent) for e in fleet.events)
    assert [p[1] for p in fleet.service.path(task.id)] == [0.5, 3.0]


def test_assignment_is_resent_until_acknowledged(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    assert len(fleet.parks()) == 1
    fleet.clock.advance(RESEND_INTERVAL_S / 2)
    fleet.service.tick()
    assert len(fleet.parks()) == 1
    for n in (2, 3):
        fleet.clock.advance(RESEND_INTERVAL_S)
        fleet.service.tick()
        assert len(fleet.parks()) == n
    assert {p.task_id for p in fleet.parks()} == {task.id}
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    for _ in range(5):
        fleet.clock.advance(RESEND_INTERVAL_S)
        fleet.service.tick()
    assert len(fleet.parks()) == 3
    assert fleet.service.counters["assignments_resent"] == 2

    # A robot that restarts and forgets its task gets it again.
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.IDLE, task_id=None)
    fleet.clock.advance(RESEND_INTERVAL_S)
    fleet.service.tick()
    assert len(fleet.parks()) == 4


def test_timeout_fails_the_task_and_stops_the_robot(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    fleet.clock.advance(29.0)
    fleet.service.tick()
    assert fleet.service.task(task.id).status == TaskStatus.DRIVING
    fleet.clock.advance(1.5)
    fleet.service.tick()
    failed = fleet.service.task(task.id)
    assert failed.status == TaskStatus.FAILED and failed.reason is not None
    assert "timeout" in failed.reason
    assert [c.task_id for c in fleet.cancels("r1")] == [task.id]
    # The robot did not hear the cancel and drives on: the cancel is re-sent.
    fleet.clock.advance(RESEND_INTERVAL_S)
    fleet.robot("r1", 0.2, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    assert len(fleet.cancels("r1")) == 2
    fleet.robot("r1", 0.2, 0.0, mode=RobotMode.DRIVING, task_id=task.id)  # rate limited
    assert len(fleet.cancels("r1")) == 2
    fleet.robot("r1", 0.2, 0.0, mode=RobotMode.HOLDING, task_id=task.id)
    assert fleet.service.robot("r1").status == RobotStatus.HOLDING


def test_lost_robot_fails_its_task_and_stays_an_obstacle(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    fleet.robot("r1", 1.0, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    fleet.bus.robot_gone("r1")
    failed = fleet.service.task(task.id)
    assert failed.status == TaskStatus.FAILED and "lost" in (failed.reason or "")
    view = fleet.service.robot("r1")
    assert view.status == RobotStatus.LOST and view.pose.x == 1.0
    with pytest.raises(GoalRejected, match="lost robot r1"):
        fleet.service.submit(req(1.5, 0.0))
    # A late state does not revive it; a new token does.
    fleet.robot("r1", 1.0, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    assert fleet.service.robot("r1").status == RobotStatus.LOST
    fleet.bus.robot_alive("r1")
    assert fleet.service.robot("r1").status == RobotStatus.DRIVING


def test_lost_robot_requeues_its_task_to_another_robot() -> None:
    f = Fleet(on_robot_lost="requeue")
    try:
        f.join("r1", 0.0, 0.0)
        f.join("r2", -5.0, 5.0)
        task = f.service.submit(req(2.0, 0.0))
        f.service.tick()
        assert f.service.task(task.id).robot_id == "r1"
        f.robot("r1", 0.5, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
        f.bus.robot_gone("r1")
        requeued = f.service.task(task.id)
        assert requeued.status == TaskStatus.QUEUED and requeued.robot_id is None
        assert "requeued" in (requeued.reason or "")
        f.service.tick()
        again = f.service.task(task.id)
        assert again.status == TaskStatus.ASSIGNED and again.robot_id == "r2"
        assert again.attempts == 2
        assert f.parks("r2")[0].task_id == task.id
    finally:
        f.service.close()


def test_cancel(fleet: Fleet) -> None:
    queued = fleet.service.submit(req(3.0, 0.0))  # no robots: stays queued
    fleet.service.tick()
    assert fleet.service.cancel(queued.id).status == TaskStatus.CANCELLED
    with pytest.raises(TaskConflict, match="already cancelled"):
        fleet.service.cancel(queued.id)
    with pytest.raises(TaskNotFound):
        fleet.service.cancel("nope")
    assert fleet.cancels() == []  # nothing was sent to a robot

    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    cancelled = fleet.service.cancel(task.id)
    assert cancelled.status == TaskStatus.CANCELLED and cancelled.reason
    assert [c.task_id for c in fleet.cancels("r1")] == [task.id]
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.HOLDING, task_id=task.id)
    fleet.clock.advance(1.0)
    fleet.service.tick()
    assert len(fleet.parks("r1")) == 1  # a cancelled task is never re-sent


def test_idempotency_key_returns_the_same_task(fleet: Fleet) -> None:
    first = fleet.service.submit(req(3.0, 0.0), idempotency_key="k1")
    again = fleet.service.submit(req(3.0, 0.0), idempotency_key="k1")
    assert again.id == first.id
    assert len(fleet.service.tasks()) == 1
    other = fleet.service.submit(req(-3.0, 0.0), idempotency_key="k2")
    assert other.id != first.id


def test_validation_errors(fleet: Fleet) -> None:
    with pytest.raises(RobotNotFound):
        fleet.service.submit(req(1.0, 1.0, robot="ghost"))
    with pytest.raises(GoalRejected, match="outside the yard"):
        fleet.service.submit(req(50.0, 0.0))
    first = fleet.service.submit(req(1.0, 1.0))
    with pytest.raises(GoalRejected, match=f"goal of task {first.id}"):
        fleet.service.submit(req(1.5, 1.0))
    fleet.service.set_obstacles([Obstacle(x=5.0, y=5.0, radius=1.0)])
    assert fleet.bus.obstacle_sets[-1].obstacles == [Obstacle(x=5.0, y=5.0, radius=1.0)]
    assert fleet.service.obstacles() == [Obstacle(x=5.0, y=5.0, radius=1.0)]
    with pytest.raises(GoalRejected, match="influence zone of obstacle 0"):
        fleet.service.submit(req(5.5, 5.0))
    assert len(fleet.service.tasks()) == 1
    with pytest.raises(TaskNotFound):
        fleet.service.task("nope")
    with pytest.raises(TaskNotFound):
        fleet.service.path("nope")
    with pytest.raises(RobotNotFound):
        fleet.service.robot("nope")


def test_named_task_waits_until_its_robot_is_free(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    fleet.join("r2", 0.0, 5.0)
    first = fleet.service.submit(req(3.0, 0.0, robot="r1"))
    second = fleet.service.submit(req(-3.0, 0.0, robot="r1"))
    fleet.service.tick()
    assert fleet.service.task(first.id).status == TaskStatus.ASSIGNED
    assert fleet.service.task(second.id).status == TaskStatus.QUEUED  # r2 idle but not named
    fleet.robot("r1", 3.0, 0.0, mode=RobotMode.ARRIVED, task_id=first.id)
    fleet.service.tick()
    assert fleet.service.task(second.id).status == TaskStatus.ASSIGNED
    assert fleet.service.task(second.id).robot_id == "r1"


def test_unnamed_tasks_go_to_robots_by_least_total_predicted_time(fleet: Fleet) -> None:
    fleet.join("a", -6.0, 0.0)
    fleet.join("b", 6.0, 0.0)
    # Submitted in the order that a first-come/first-robot rule would get wrong.
    east = fleet.service.submit(req(7.0, 2.0))
    west = fleet.service.submit(req(-7.0, 2.0))
    fleet.service.tick()
    assert fleet.service.task(east.id).robot_id == "b"
    assert fleet.service.task(west.id).robot_id == "a"


def test_direction_request_is_obeyed(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(0.0, 3.0, direction="cw"))
    fleet.service.tick()
    assert fleet.service.task(task.id).law == "cw"
    assert fleet.parks("r1")[0].law == "cw"


def test_restart_recovers_unfinished_tasks_from_the_store() -> None:
    store = MemoryTaskStore()
    first = Fleet(store=store)
    first.join("r1", 0.0, 0.0)
    running = first.service.submit(req(3.0, 0.0))
    first.service.tick()
    waiting = first.service.submit(req(-3.0, 3.0, robot="r1"))
    first.robot("r1", 0.5, 0.0, mode=RobotMode.DRIVING, task_id=running.id)
    first.service.close()
    first.service.close()  # idempotent
    assert first.bus.closed

    second = Fleet(store=store)
    try:
        assert second.service.task(running.id).status == TaskStatus.DRIVING
        assert second.service.task(waiting.id).status == TaskStatus.QUEUED
        second.bus.robot_alive("r1")
        second.service.tick()  # robot state unknown yet: the assignment is re-sent
        assert [p.task_id for p in second.parks("r1")] == [running.id]
        second.robot("r1", 3.0, 0.0, mode=RobotMode.ARRIVED, task_id=running.id)
        assert second.service.task(running.id).status == TaskStatus.SUCCEEDED
        second.service.tick()
        assert second.service.task(waiting.id).status == TaskStatus.ASSIGNED
    finally:
        second.service.close()


def test_listeners_may_call_back_and_unsubscribe(fleet: Fleet) -> None:
    seen: list[int] = []

    def listener(event: FleetEvent) -> None:
        seen.append(len(fleet.service.tasks()))  # re-entrant call must not deadlock

    unsubscribe = fleet.service.add_listener(listener)
    fleet.service.submit(req(1.0, 1.0))
    unsubscribe()
    fleet.service.submit(req(-4.0, 1.0))
    assert seen == [1]

    def broken(event: FleetEvent) -> None:
        raise RuntimeError("boom")

    fleet.service.add_listener(broken)
    fleet.service.submit(req(4.0, -4.0))
    assert fleet.service.counters["listener_errors"] == 1


def test_parked_robot_blocks_goals_near_it(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    fleet.robot("r1", 3.0, 0.0, mode=RobotMode.ARRIVED, task_id=task.id)
    with pytest.raises(GoalRejected, match="arrived robot r1"):
        fleet.service.submit(req(3.5, 0.5))
    # ... but the robot itself may be sent there again.
    fleet.service.submit(req(3.5, 0.5, robot="r1"))
    assert math.isfinite(fleet.service.robot("r1").last_seen)


def test_background_thread_dispatches() -> None:
    """Nobody calls tick(): the service's own thread plans and sends the assignment."""
    bus = MemoryBus()
    service = FleetService(Settings(), bus, MemoryTaskStore())
    with service:
        service.start()  # idempotent
        bus.robot_alive("r1")
        bus.deliver_state(RobotState(robot_id="r1", seq=1, stamp=0.0, pose=Pose(x=0.0, y=0.0)))
        task = service.submit(req(4.0, 0.0))
        wait_for(lambda: bool(bus.sent("r1")), 30, "the assignment from the service's thread")
        sent = bus.sent("r1")[0]
        assert isinstance(sent, ParkAssignment) and sent.task_id == task.id
        assert service.task(task.id).robot_id == "r1"
    service.close()  # idempotent after the with block


#: The swaps below were built around the paper's Table 1 gains (the defaults before the
#: yard tuning); the tasks name them so the replanning is tested, not the defaults.
TABLE_1 = dict(SCENARIOS["first"].gains)


def _other(law: Law | None) -> Law:
    return "cw" if law == "ccw" else "ccw"


@pytest.fixture
def straight_fleet() -> Iterator[Fleet]:
    """A fleet whose planner gives no open approach points (the laws' own way)."""
    f = Fleet(task_timeout_s=30.0, planner=partial(plan, config=PlannerConfig(open_approach_m=())))
    yield f
    f.service.close()


def test_a_replan_that_changes_a_robot_under_way_sends_the_next_revision(
    straight_fleet: Fleet,
) -> None:
    """Two robots swap sides; the second one's task fixes the opposite sense of the first
    one's law, which would make them meet head on (mixed senses collide). Driving the laws'
    own way (with an open approach point the second robot goes round the first one's way
    instead), the planner must change the robot under way (flip its law, or stop it for a
    while so the other passes first): it gets revision 1 carrying that change, re-sent
    until acknowledged."""
    fleet = straight_fleet
    fleet.service.lead_time_max = 0.0  # plan from the reported poses (deterministic)
    q = math.pi / 4
    fleet.join("r0", 4.0, 0.0)
    fleet.robot("r0", 4.0, 0.0, math.pi + q)
    first = fleet.service.submit(
        TaskRequest(goal=Pose(x=-4.0, y=0.0, theta=math.pi - q), robot_id="r0", law_gains=TABLE_1)
    )
    fleet.service.tick()
    (park0,) = fleet.parks("r0")
    assert park0.revision == 0
    assert park0.start_delay_s == 0.0 and not park0.hold  # alone: it drives at once
    fleet.robot("r0", 4.0, 0.0, math.pi + q, RobotMode.DRIVING, first.id)
    # r1 comes up on r0's goal (where r0 is bound: it cannot arrive before r1 leaves)
    fleet.join("r1", -4.0, 0.0)
    fleet.robot("r1", -4.0, 0.0, q)
    assert fleet.service.task(first.id).status == TaskStatus.DRIVING

    second = fleet.service.submit(
        TaskRequest(
            goal=Pose(x=4.0, y=0.0, theta=-q),
            robot_id="r1",
            direction=_other(park0.law),
            law_gains=TABLE_1,
        )
    )
    fleet.service.tick()
    revised = fleet.service.task(first.id)
    assert revised.revision == 1
    assert revised.law != park0.law or revised.start_delay_s > 0 or revised.hold
    assert revised.status == TaskStatus.DRIVING
    assert fleet.service.task(second.id).law == _other(park0.law)
    _, park1 = fleet.parks("r0")
    assert (park1.task_id, park1.revision, park1.law) == (first.id, 1, revised.law)
    assert (park1.start_delay_s, park1.hold) == (revised.start_delay_s, revised.hold)
    assert park1.gains == revised.request.gains_for(revised.law)
    # stored before announced, as every transition
    assert [ev for _, ev, _ in fleet.store.history(first.id)][-1] == "replanned"
    assert fleet.task_statuses(first.id)[-1] == TaskStatus.DRIVING
    assert fleet.service.counters["replans"] == 1

    # Re-sent until a state reports the revision; then no more.
    fleet.clock.advance(RESEND_INTERVAL_S)
    fleet.service.tick()
    assert [p.revision for p in fleet.parks("r0")] == [0, 1, 1]
    fleet.robot("r0", 3.9, 0.0, math.pi + q, RobotMode.DRIVING, first.id, revision=1)
    fleet.clock.advance(RESEND_INTERVAL_S)
    fleet.service.tick()
    assert len(fleet.parks("r0")) == 3

    # The robot's side: revision 1 replaces revision 0; late copies of revision 0 do not.
    task = None
    for msg in [park0, park1, park0, park1, park0]:
        task = apply_assignment(task, msg)
    assert task is not None and task.assignment == park1


def test_a_safe_robot_under_way_is_not_replanned(fleet: Fleet) -> None:
    fleet.service.lead_time_max = 0.0
    q = math.pi / 4
    fleet.join("r0", 4.0, 0.0)
    fleet.robot("r0", 4.0, 0.0, math.pi + q)
    first = fleet.service.submit(
        TaskRequest(goal=Pose(x=-4.0, y=0.0, theta=math.pi - q), robot_id="r0", law_gains=TABLE_1)
    )
    fleet.service.tick()
    (park0,) = fleet.parks("r0")
    assert park0.start_delay_s == 0.0 and not park0.hold
    fleet.robot("r0", 4.0, 0.0, math.pi + q, RobotMode.DRIVING, first.id)
    fleet.join("r1", -4.0, 0.0)  # on r0's goal, then off to r0's start the same way round
    fleet.robot("r1", -4.0, 0.0, q)
    fleet.service.submit(
        TaskRequest(
            goal=Pose(x=4.0, y=0.0, theta=-q), robot_id="r1", direction=park0.law, law_gains=TABLE_1
        )
    )
    fleet.service.tick()
    assert fleet.parks("r0") == [park0]
    assert fleet.service.task(first.id).revision == 0


def _assert_indexes_match(service: FleetService) -> None:
    """The service's incremental indexes equal the ones recomputed from every active task."""
    ledger = service._ledger
    active = dict(ledger.active)
    assert ledger.queued == {k: t for k, t in active.items() if t.status == TaskStatus.QUEUED}
    under_way = {k: t for k, t in active.items() if t.status.under_way and t.robot_id is not None}
    assert ledger.under_way == under_way
    assert ledger.robot_task == {t.robot_id: k for k, t in under_way.items()}
    claims: dict[str, int] = {}
    for t in active.values():
        for rid in {t.robot_id, t.request.robot_id} - {None}:
            assert rid is not None
            claims[rid] = claims.get(rid, 0) + 1
    assert dict(ledger.claims) == claims
    assert len(ledger.goals) == len(active)
    for t in active.values():
        assert t.id in ledger.goals


def test_incremental_indexes_follow_every_transition() -> None:
    f = Fleet(on_robot_lost="requeue", task_timeout_s=30.0)
    try:
        for i, rid in enumerate(("r1", "r2", "r3")):
            f.join(rid, -6.0 + 3.0 * i, -6.0)
        tasks = [f.service.submit(req(-6.0 + 3.0 * k, 6.0)) for k in range(5)]
        named = f.service.submit(req(6.0, 0.0, robot="r2"))
        _assert_indexes_match(f.service)
        f.service.tick()
        _assert_indexes_match(f.service)
        under_way = [t for t in f.service._ledger.active.values() if t.robot_id is not None]
        assert len(under_way) == 3
        a, b, c = under_way
        assert a.robot_id and b.robot_id and c.robot_id
        f.robot(a.robot_id, 0.0, 0.0, mode=RobotMode.DRIVING, task_id=a.id)
        _assert_indexes_match(f.service)
        g = a.request.goal
        f.robot(a.robot_id, g.x, g.y, mode=RobotMode.ARRIVED, task_id=a.id)
        _assert_indexes_match(f.service)
        f.service.cancel(b.id)
        _assert_indexes_match(f.service)
        f.bus.robot_gone(c.robot_id)  # requeued
        _assert_indexes_match(f.service)
        f.service.tick()
        _assert_indexes_match(f.service)
        f.clock.advance(31.0)  # every task under way times out
        f.service.tick()
        _assert_indexes_match(f.service)
        for t in [*tasks, named]:
            if not f.service.task(t.id).status.final:
                f.service.cancel(t.id)
        _assert_indexes_match(f.service)
        assert not f.service._ledger.active and len(f.service._ledger.goals) == 0
    finally:
        f.service.close()


def _hold_task_writes(f: Fleet) -> tuple[threading.Event, threading.Event]:
    """Make the store's task writes wait: ``entered`` is set when one starts, and it
    completes once ``release`` is set."""
    entered, release = threading.Event(), threading.Event()
    save_new = f.store.save_new

    def slow_save_new(task: Task, key: str | None) -> Task:
        entered.set()
        release.wait(5.0)
        return save_new(task, key)

    f.store.save_new = slow_save_new  # type: ignore[method-assign]
    return entered, release


def test_a_goal_is_reserved_while_its_task_is_written() -> None:
    """Two submits of the same spot: the second is rejected even while the first is still
    being stored (the reservation is taken under the lock, the write happens outside it)."""
    f = Fleet()
    try:
        entered, release = _hold_task_writes(f)
        first: list[Task] = []
        writer = threading.Thread(target=lambda: first.append(f.service.submit(req(1.0, 1.0))))
        writer.start()
        assert entered.wait(5.0)
        assert f.service._ledger.active == {}  # not dispatchable before it is stored
        with pytest.raises(GoalRejected, match="the goal of task"):
            f.service.submit(req(1.2, 1.0))
        release.set()
        writer.join(5.0)
        assert f.service.task(first[0].id).status == TaskStatus.QUEUED
        _assert_indexes_match(f.service)
    finally:
        f.service.close()


def test_concurrent_requests_with_one_idempotency_key_get_one_task() -> None:
    """Same key, same goal, while the first is still being written: the others wait for it
    and get its task (not a 'too near the goal' rejection)."""
    f = Fleet()
    try:
        entered, release = _hold_task_writes(f)
        got: list[Task] = []
        first = threading.Thread(target=lambda: got.append(f.service.submit(req(1, 1), "k")))
        first.start()
        assert entered.wait(5.0)
        others = [
            threading.Thread(target=lambda: got.append(f.service.submit(req(1, 1), "k")))
            for _ in range(3)
        ]
        for t in others:
            t.start()
        release.set()
        for t in [first, *others]:
            t.join(10.0)
        assert len(got) == 4 and len({t.id for t in got}) == 1
        _assert_indexes_match(f.service)
    finally:
        f.service.close()
