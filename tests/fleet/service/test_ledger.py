"""The task ledger alone: transitions and the effects they return (pure, no threads)."""

from __future__ import annotations

from typing import Any

import pytest

from fleet.core.planner import TaskDecision
from fleet.core.tasks import Task, TaskEvent, TaskNotFound, TaskRequest, TaskStatus
from fleet.core.wire import CancelAssignment, ParkAssignment, Pose, RobotMode, RobotState
from fleet.service.effects import Effects, Notify, Publish, StoreWrite
from fleet.service.ledger import RELEASED_REASON, LedgerConfig, Outcome, TaskLedger

WALL = 1.7e9


def task(task_id: str, x: float = 3.0, robot: str | None = None, **kw: Any) -> Task:
    request = TaskRequest(goal=Pose(x=x, y=0.0), robot_id=robot, **kw)
    return Task(id=task_id, request=request, created_at=WALL, updated_at=WALL)


def state(rid: str, task_id: str | None, mode: RobotMode, seq: int = 1, **kw: Any) -> RobotState:
    return RobotState(
        robot_id=rid,
        seq=seq,
        stamp=0.0,
        pose=Pose(x=kw.pop("x", 0.0), y=kw.pop("y", 0.0)),
        mode=mode,
        task_id=task_id,
        **kw,
    )


def assign(tid: str, rid: str, **kw: Any) -> TaskDecision:
    return TaskDecision(tid, rid, "assign", kw.pop("law", "cw"), **kw)


def kinds(effects: Effects) -> list[str]:
    """The effects in order, as short names: store:<event>, publish:<kind>, notify:<status>."""
    out = []
    for e in effects:
        if isinstance(e, StoreWrite):
            out.append(f"store:{e.event}")
        elif isinstance(e, Publish):
            out.append(f"publish:{e.message.kind}")
        elif isinstance(e, Notify) and isinstance(e.event, TaskEvent):
            out.append(f"notify:{e.event.task.status.value}")
    return out


@pytest.fixture
def ledger() -> TaskLedger:
    return TaskLedger(LedgerConfig(task_timeout_s=30.0, resend_interval_s=0.2, control_hz=50.0))


def applied(ledger: TaskLedger, d: TaskDecision, now: float = 0.0, **kw: Any) -> Effects:
    outcome, effects = ledger.apply(
        d,
        robot_available=kw.pop("robot_available", True),
        plan_safe=kw.pop("plan_safe", True),
        origin_seq=kw.pop("origin_seq", None),
        now=now,
        wall=WALL + now,
    )
    assert outcome is Outcome.APPLIED, outcome
    return effects


def test_a_task_goes_queued_assigned_driving_succeeded_with_its_effects(ledger: TaskLedger) -> None:
    assert kinds(ledger.add(task("t1"))) == ["notify:queued"]
    assert dict(ledger.queued) == {"t1": ledger.active["t1"]}

    effects = applied(ledger, assign("t1", "r1", start_delay_s=1.5))
    assert kinds(effects) == ["store:assigned", "notify:assigned", "publish:park"]
    (park,) = [e.message for e in effects if isinstance(e, Publish)]
    assert isinstance(park, ParkAssignment)
    assert (park.robot_id, park.law, park.start_delay_s, park.hold) == ("r1", "cw", 1.5, False)
    t = ledger.active["t1"]
    assert (t.status, t.robot_id, t.attempts, t.start_delay_s) == (
        TaskStatus.ASSIGNED,
        "r1",
        1,
        1.5,
    )
    assert ledger.task_of_robot("r1") == t and not ledger.queued

    seen = ledger.observe(state("r1", "t1", RobotMode.WAITING), 0.0, WALL)
    assert kinds(seen.effects) == ["store:acknowledged", "notify:driving"]
    assert ledger.sent_revision_acknowledged("t1")

    seen = ledger.observe(state("r1", "t1", RobotMode.ARRIVED, seq=2, x=3.0), 0.0, WALL + 1)
    assert seen.finished
    assert kinds(seen.effects) == ["store:succeeded", "notify:succeeded"]
    assert not ledger.active and not ledger.robot_task and len(ledger.goals) == 0
    assert ledger.finished_status("t1") is TaskStatus.SUCCEEDED
    assert [p[1] for p in ledger.paths.get("t1") or []] == [0.0, 3.0]


def test_a_hold_makes_the_task_wait_with_the_reason_and_a_resume_assigns_it_again(
    ledger: TaskLedger,
) -> None:
    ledger.add(task("t1"))
    effects = applied(ledger, assign("t1", "r1", hold=True, reason="waiting: r2 in the way"))
    held = ledger.active["t1"]
    assert held.status is TaskStatus.WAITING and held.reason == "waiting: r2 in the way"
    park = next(e.message for e in effects if isinstance(e, Publish))
    assert isinstance(park, ParkAssignment) and park.hold
    ledger.observe(state("r1", "t1", RobotMode.WAITING), 0.0, WALL)
    assert ledger.active["t1"].status is TaskStatus.WAITING  # acknowledged, still waiting

    resume = TaskDecision("t1", "r1", "revise", "cw", revision=0)
    effects = applied(ledger, resume, now=1.0)
    assert kinds(effects) == ["store:resumed", "notify:assigned", "publish:park"]
    resumed = ledger.active["t1"]
    assert (resumed.status, resumed.revision, resumed.hold, resumed.reason) == (
        TaskStatus.ASSIGNED,
        1,
        False,
        None,
    )
    # A state of the old revision does not acknowledge the resume; the new one does.
    assert not ledger.observe(state("r1", "t1", RobotMode.WAITING, seq=2), 0.0, WALL).effects
    seen = ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=3, revision=1), 0.0, WALL)
    assert kinds(seen.effects) == ["store:acknowledged", "notify:driving"]


def test_a_flip_keeps_the_status_and_sends_the_next_revision(ledger: TaskLedger) -> None:
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1", law="ccw"))
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL)
    effects = applied(ledger, TaskDecision("t1", "r1", "revise", "cw", revision=0))
    assert kinds(effects) == ["store:replanned", "notify:driving", "publish:park"]
    t = ledger.active["t1"]
    assert (t.law, t.revision, t.status) == ("cw", 1, TaskStatus.DRIVING)


def test_decisions_on_changed_tasks_are_stale_and_unchanged_ones_send_nothing(
    ledger: TaskLedger,
) -> None:
    ledger.add(task("t1"))
    ledger.add(task("t2", x=-3.0, robot="r2"))

    def outcome(d: TaskDecision, available: bool = True) -> Outcome:
        return ledger.apply(
            d, robot_available=available, plan_safe=True, origin_seq=None, now=0.0, wall=WALL
        )[0]

    assert outcome(assign("nope", "r1")) is Outcome.STALE
    assert outcome(assign("t1", "r1"), available=False) is Outcome.STALE
    assert outcome(assign("t2", "r1")) is Outcome.STALE  # t2 names r2
    assert outcome(assign("t1", "r1", revision=3)) is Outcome.STALE
    assert outcome(assign("t1", "r1")) is Outcome.APPLIED
    assert outcome(assign("t1", "r1")) is Outcome.STALE  # no longer queued
    assert outcome(assign("t2", "r1")) is Outcome.STALE  # r1 is busy now
    same = TaskDecision("t1", "r1", "revise", "cw", revision=0)
    assert outcome(same) is Outcome.UNCHANGED
    assert outcome(TaskDecision("t1", "r1", "keep", "cw", revision=0)) is Outcome.UNCHANGED
    assert outcome(TaskDecision("t1", "r9", "revise", "ccw", revision=0)) is Outcome.STALE
    assert outcome(TaskDecision("t1", "r1", "revise", "ccw", revision=0)) is Outcome.APPLIED
    assert outcome(TaskDecision("t1", "r1", "revise", "cw", revision=0)) is Outcome.STALE


def test_an_unsafe_plan_never_starts_or_resumes_a_robot(ledger: TaskLedger) -> None:
    ledger.add(task("t1"))
    ledger.add(task("t2", x=-3.0))

    def outcome(d: TaskDecision) -> Outcome:
        return ledger.apply(
            d, robot_available=True, plan_safe=False, origin_seq=None, now=0.0, wall=WALL
        )[0]

    assert outcome(assign("t1", "r1")) is Outcome.UNSAFE
    assert ledger.active["t1"].status is TaskStatus.QUEUED
    assert outcome(assign("t1", "r1", hold=True)) is Outcome.APPLIED  # holding is safe
    assert outcome(TaskDecision("t1", "r1", "revise", "cw", revision=0)) is Outcome.UNSAFE
    assert ledger.active["t1"].hold
    # Nor is a robot already moving re-planned by it (a new law or a shorter start delay
    # moves it otherwise than the last checked plan); it may be held.
    applied(ledger, assign("t2", "r2", law="ccw", start_delay_s=5.0))
    assert outcome(TaskDecision("t2", "r2", "revise", "cw", revision=0)) is Outcome.UNSAFE
    assert outcome(TaskDecision("t2", "r2", "revise", "ccw", revision=0)) is Outcome.UNSAFE
    assert ledger.active["t2"].start_delay_s == 5.0
    hold = TaskDecision("t2", "r2", "revise", "ccw", revision=0, hold=True)
    assert outcome(hold) is Outcome.APPLIED


def test_resends_until_acknowledged_and_timeouts_stop_the_robot(ledger: TaskLedger) -> None:
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1"), now=0.0)
    assert ledger.resends(0.1) == []
    assert kinds(ledger.resends(0.2)) == ["publish:park"]
    assert ledger.resends(0.3) == []
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL)
    assert ledger.resends(10.0) == []
    ledger.observe(state("r1", None, RobotMode.IDLE, seq=2), 0.0, WALL)  # restarted: forgot it
    assert kinds(ledger.resends(10.0)) == ["publish:park"]

    assert ledger.timeouts(29.9, WALL) == []
    effects = ledger.timeouts(30.0, WALL + 30)
    assert kinds(effects) == ["store:failed", "notify:failed", "publish:cancel"]
    cancel = effects[-1]
    assert isinstance(cancel, Publish) and cancel.message == CancelAssignment(
        robot_id="r1", task_id="t1"
    )
    failed = next(e.task for e in effects if isinstance(e, StoreWrite))
    assert failed.status is TaskStatus.FAILED and "timeout" in (failed.reason or "")


def test_a_state_of_a_finished_task_is_a_stray_to_stop(ledger: TaskLedger) -> None:
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1"))
    _, effects = ledger.cancel("t1", WALL)
    assert kinds(effects) == ["store:cancelled", "notify:cancelled", "publish:cancel"]
    assert ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL).stray
    assert not ledger.observe(state("r1", "t1", RobotMode.HOLDING), 0.0, WALL).stray
    with pytest.raises(TaskNotFound):
        ledger.cancel("t1", WALL)


@pytest.mark.parametrize("on_lost", ["fail", "requeue"])
def test_a_lost_robot_fails_or_requeues_its_task(on_lost: str) -> None:
    ledger = TaskLedger(LedgerConfig(on_robot_lost=on_lost))  # type: ignore[arg-type]
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1", hold=True, start_delay_s=2.0))
    effects = ledger.robot_lost("r1", 1.0, WALL)
    t = next(e.task for e in effects if isinstance(e, StoreWrite))
    if on_lost == "fail":
        assert t.status is TaskStatus.FAILED and "lost" in (t.reason or "")
    else:
        assert (t.status, t.robot_id, t.law, t.hold, t.start_delay_s) == (
            TaskStatus.QUEUED,
            None,
            None,
            False,
            0.0,
        )
        assert "requeued" in (t.reason or "")
        assert ledger.queued["t1"] == t
    assert ledger.robot_lost("r1", 1.0, WALL) == []  # nothing left on it


def test_removing_a_robot_fails_the_queued_tasks_that_name_it(ledger: TaskLedger) -> None:
    ledger.add(task("t1", robot="r1"))
    ledger.add(task("t2", x=-3.0, robot="r2"))
    effects = ledger.robot_removed("r1", WALL)
    assert kinds(effects) == ["store:failed", "notify:failed"]
    assert list(ledger.active) == ["t2"] and "r1" not in ledger.claims


def test_a_robot_leaving_its_corridor_trips_it_once(ledger: TaskLedger) -> None:
    ledger.add(task("t1"))
    corridor = ((0.0, 0.0, 0.0), (1.0, 1.0, 0.0), (2.0, 2.0, 0.0))
    applied(ledger, assign("t1", "r1", corridor=corridor))
    # The first acknowledging state (seq 100) is t = 0; 50 states later t = 1 s.
    assert not ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=100), 0.0, WALL).off_corridor
    on = ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=150, x=1.2), 0.0, WALL)
    assert not on.off_corridor  # 0.2 m <= 0.3 m
    off = ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=175, x=1.0), 0.0, WALL)
    assert off.off_corridor  # predicted 1.5 m at t = 1.5 s: 0.5 m away
    again = ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=176, x=1.0), 0.0, WALL)
    assert not again.off_corridor  # one departure, one re-plan
    # A kept decision brings a new corridor, anchored at the snapshot (origin seq given).
    keep = TaskDecision("t1", "r1", "keep", "cw", revision=0, corridor=((0.0, 1.0, 0.0),))
    outcome, _ = ledger.apply(
        keep, robot_available=False, plan_safe=True, origin_seq=176.0, now=0.0, wall=WALL
    )
    assert outcome is Outcome.UNCHANGED
    assert ledger.observe(
        state("r1", "t1", RobotMode.DRIVING, seq=200, x=1.5), 0.0, WALL
    ).off_corridor


def test_recovered_tasks_under_way_are_resent_at_once(ledger: TaskLedger) -> None:
    running = task("t1").model_copy(
        update={"status": TaskStatus.DRIVING, "robot_id": "r1", "law": "cw", "revision": 2}
    )
    assert ledger.recover([running, task("t2", x=-3.0)], now=5.0) == 2
    (park,) = [e.message for e in ledger.resends(5.0) if isinstance(e, Publish)]
    assert isinstance(park, ParkAssignment) and (park.task_id, park.revision) == ("t1", 2)
    assert list(ledger.queued) == ["t2"]
    assert ledger.timeouts(34.9, WALL) == [] and ledger.timeouts(35.0, WALL)


def test_an_operator_hold_stops_the_timeout_and_is_stored_with_the_reason(
    ledger: TaskLedger,
) -> None:
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1"), now=0.0)  # deadline 30 s
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 1.0, WALL)
    effects = ledger.hold_robot("r1", "emergency stop by cli: drill", 10.0, WALL + 10)
    # a held revision, sent: let go, the robot stands until a plan resumes it
    assert kinds(effects) == ["store:operator_hold", "notify:waiting", "publish:park"]
    held = ledger.active["t1"]
    assert (held.reason, held.hold, held.revision) == ("emergency stop by cli: drill", True, 1)
    assert ledger.hold_robot("r1", "again", 11.0, WALL) == []  # held once
    assert ledger.timeouts(100.0, WALL + 100) == []  # no deadline while held
    start = TaskDecision("t1", "r1", "revise", "cw", revision=1)
    outcome, _ = ledger.apply(
        start, robot_available=False, plan_safe=True, origin_seq=None, now=50.0, wall=WALL
    )
    assert outcome is Outcome.UNCHANGED  # an operator holds it: no plan starts it
    effects = ledger.release_robot("r1", 100.0, WALL + 100)
    assert kinds(effects) == ["store:operator_release", "notify:waiting"]
    assert ledger.active["t1"].reason == RELEASED_REASON and dict(ledger.held) == {}
    assert ledger.release_robot("r1", 101.0, WALL) == []
    assert kinds(applied(ledger, start, now=101.0)) == ["store:resumed", "notify:assigned",
                                                         "publish:park"]  # fmt: skip
    # 10 s ran before the hold: the deadline moved on by the 90 s held, to 120 s.
    assert ledger.timeouts(119.9, WALL) == [] and ledger.timeouts(120.0, WALL)


def test_a_held_robot_without_a_task_is_remembered_until_removed(ledger: TaskLedger) -> None:
    assert ledger.hold_robot("r1", "paused", 0.0, WALL) == []
    assert dict(ledger.held) == {"r1": "paused"} and ledger.sizes()["robots_held"] == 1
    ledger.robot_removed("r1", WALL)
    assert dict(ledger.held) == {}


def test_a_decommissioned_robots_task_is_requeued_as_a_new_revision_and_it_is_stopped(
    ledger: TaskLedger,
) -> None:
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1"))
    effects = ledger.robot_decommissioned("r1", WALL)
    assert kinds(effects) == ["store:requeued", "notify:queued", "publish:cancel"]
    t = ledger.queued["t1"]
    assert (t.robot_id, t.revision, t.reason) == (None, 1, "robot r1 decommissioned; requeued")
    assert ledger.robot_decommissioned("r1", WALL) == []


def test_a_stuck_task_is_recovered_in_order_then_failed() -> None:
    ledger = TaskLedger(LedgerConfig(task_timeout_s=1e6, stuck_after_s=30.0))
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1", law="ccw"), now=0.0)
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL)
    assert ledger.stuck(29.0) == [] and [t.id for t in ledger.stuck(30.0)] == ["t1"]

    effects = ledger.recover_stuck("t1", "a peer in the way", 30.0, WALL)
    # a held revision with the other law: the robot stands until a plan resumes it
    assert kinds(effects) == ["store:recovery", "notify:waiting", "publish:park"]
    t = ledger.active["t1"]
    assert (t.law, t.revision, t.hold, t.status) == ("cw", 1, True, TaskStatus.WAITING)
    assert t.reason == "stuck: a peer in the way; recovery 1: flip"
    assert ledger.pinned() == {"t1": "cw"}  # the planner keeps the flipped law
    assert ledger.stuck(1000.0) == []  # held on purpose: not stuck

    def resume(revision: int, now: float, safe: bool = True) -> Outcome:
        decision = TaskDecision("t1", "r1", "revise", "cw", revision=revision)
        return ledger.apply(
            decision, robot_available=False, plan_safe=safe, origin_seq=None, now=now, wall=WALL
        )[0]

    assert resume(1, 31.0, safe=False) is Outcome.UNSAFE  # only a checked plan starts it
    assert resume(1, 31.0) is Outcome.APPLIED
    ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=3, revision=2), 46.0, WALL)
    (stuck,) = ledger.stuck(76.0)
    ledger.recover_stuck(stuck.id, "no progress", 76.0, WALL)
    t = ledger.active["t1"]
    assert (t.law, t.revision, t.hold) == ("cw", 3, True)  # wait: held, the same law
    assert t.reason == "stuck: no progress; recovery 2: wait"
    assert resume(3, 77.0) is Outcome.APPLIED
    ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=4, revision=4), 78.0, WALL)

    (stuck,) = ledger.stuck(108.0)
    effects = ledger.recover_stuck("t1", "no progress", 108.0, WALL)
    assert kinds(effects) == ["store:recovery", "notify:queued", "publish:cancel"]
    assert ledger.avoided() == {"t1": "r1"} and ledger.pinned() == {}  # another robot: free
    applied(ledger, assign("t1", "r2", revision=5), now=109.0)
    assert ledger.avoided() == {}  # under way again: nothing to avoid in a plan
    ledger.hold_robot("r2", "paused", 110.0, WALL)
    assert ledger.stuck(1000.0) == []  # held: not stuck
    ledger.release_robot("r2", 1000.0, WALL)
    assert ledger.stuck(1030.0) == []  # let go, it stands held until a plan resumes it
    applied(ledger, TaskDecision("t1", "r2", "revise", "cw", revision=6), now=1000.0)
    ledger.observe(state("r2", "t1", RobotMode.DRIVING, seq=5, revision=7), 1000.0, WALL)
    (stuck,) = ledger.stuck(1030.0)
    effects = ledger.recover_stuck(stuck.id, "no progress", 1030.0, WALL)
    assert kinds(effects) == ["store:failed", "notify:failed", "publish:cancel"]
    failed = next(e.task for e in effects if isinstance(e, StoreWrite))
    assert failed.reason == "stuck: no progress; 3 recoveries did not help"
    assert ledger.sizes()["tasks_watched_stuck"] == 0


def test_a_pinned_law_holds_until_its_robot_has_come_nearer_its_goal() -> None:
    """A stuck recovery pins the other law where the robot was held (3 m short of its
    goal); the planner keeps it until the robot is ``pin_release_m`` nearer its goal --
    it has left that place -- and then chooses the law again (near the goal: the faster)."""
    ledger = TaskLedger(LedgerConfig(task_timeout_s=1e6, stuck_after_s=30.0))
    ledger.add(task("t1"))  # goal (3, 0)
    applied(ledger, assign("t1", "r1", law="ccw"), now=0.0)
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL)
    (stuck,) = ledger.stuck(30.0)
    ledger.recover_stuck(stuck.id, "an obstacle in the way", 30.0, WALL)
    assert ledger.pinned() == {"t1": "cw"}
    resume = TaskDecision("t1", "r1", "revise", "cw", revision=1)
    ledger.apply(resume, robot_available=False, plan_safe=True, origin_seq=None, now=31.0,
                 wall=WALL)  # fmt: skip
    for seq, (now, x) in enumerate([(32.0, -1.0), (33.0, 0.4), (34.0, 0.45)], start=2):
        ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=seq, revision=2, x=x), now, WALL)
        assert ledger.pinned() == {"t1": "cw"}  # round the way it was held: not 0.5 m nearer
    ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=5, revision=2, x=0.55), 35.0, WALL)
    assert ledger.pinned() == {}


def test_a_released_pin_stays_released_when_its_robot_backs_away() -> None:
    ledger = TaskLedger(LedgerConfig(task_timeout_s=1e6, stuck_after_s=30.0))
    ledger.add(task("t1"))  # goal (3, 0)
    applied(ledger, assign("t1", "r1", law="ccw"), now=0.0)
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL)
    ledger.recover_stuck("t1", "an obstacle in the way", 30.0, WALL)
    resume = TaskDecision("t1", "r1", "revise", "cw", revision=1)
    ledger.apply(resume, robot_available=False, plan_safe=True, origin_seq=None, now=31.0,
                 wall=WALL)  # fmt: skip
    ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=2, revision=2, x=1.0), 32.0, WALL)
    assert ledger.pinned() == {}
    ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=3, revision=2, x=-1.0), 33.0, WALL)
    assert ledger.pinned() == {}  # the planner keeps choosing: no flip back and forth


def test_a_law_pinned_before_its_robot_was_measured_stays_pinned(ledger: TaskLedger) -> None:
    ledger.add(task("t1"))
    applied(ledger, assign("t1", "r1", law="ccw"))
    ledger.break_standoff("t1", "nose to nose", 1.0, WALL)  # no state of r1 seen yet
    ledger.observe(state("r1", "t1", RobotMode.WAITING, seq=2, revision=1, x=2.9), 2.0, WALL)
    assert ledger.pinned() == {"t1": "cw"}


def test_a_bay_is_held_from_the_reservation_until_the_task_ends(ledger: TaskLedger) -> None:
    t1 = task("t1", bay="A1")
    ledger.reserve(t1)
    assert ledger.bays.holder("A1") == "t1"
    ledger.release("t1")  # not stored after all
    assert ledger.bays.holder("A1") is None
    ledger.reserve(t1)
    ledger.add(t1)
    ledger.release("t1")  # stored: the reservation stays with the active task
    assert ledger.bays.holder("A1") == "t1"
    ledger.cancel("t1", WALL)
    assert ledger.bays.holder("A1") is None and ledger.sizes()["bays_reserved"] == 0


def test_version_rises_with_every_task_transition_and_operator_hold(ledger: TaskLedger) -> None:
    seen = [ledger.version]

    def rose() -> bool:
        seen.append(ledger.version)
        return seen[-1] > seen[-2]

    ledger.reserve(task("t1"))
    assert not rose()  # a reservation is not planned
    ledger.add(task("t1"))
    assert rose()
    applied(ledger, assign("t1", "r1"))
    assert rose()
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), now=0.1, wall=WALL)
    assert rose()  # acknowledged: driving
    ledger.observe(state("r1", "t1", RobotMode.DRIVING, seq=2), now=0.2, wall=WALL)
    assert not rose()  # progress only
    ledger.hold_robot("r1", "paused", now=0.3, wall=WALL)
    assert rose()
    ledger.hold_robot("r1", "paused", now=0.3, wall=WALL)
    assert not rose()  # already held
    ledger.release_robot("r1", now=0.4, wall=WALL)
    assert rose()
    ledger.cancel("t1", WALL)
    assert rose()


def test_a_new_way_round_is_a_revision_and_the_rest_of_the_route_is_not(
    ledger: TaskLedger,
) -> None:
    route = ((0.0, 2.1), (2.0, 0.0))
    ledger.add(task("t1"))
    effects = applied(ledger, assign("t1", "r1", law="cw", route=route))
    (sent,) = [e.message for e in effects if isinstance(e, Publish)]
    assert isinstance(sent, ParkAssignment) and [tuple(p) for p in sent.route] == list(route)
    ledger.observe(state("r1", "t1", RobotMode.DRIVING), 0.0, WALL)
    rest = TaskDecision("t1", "r1", "keep", "cw", revision=0, route=route[1:])
    outcome, effects = ledger.apply(
        rest, robot_available=True, plan_safe=True, origin_seq=None, now=0.0, wall=WALL
    )
    assert outcome is Outcome.UNCHANGED and effects == []  # the rest of it: nothing to send
    done = TaskDecision("t1", "r1", "keep", "cw", revision=0, route=(), last_leg=True)
    outcome, effects = ledger.apply(
        done, robot_available=True, plan_safe=True, origin_seq=None, now=0.0, wall=WALL
    )
    assert outcome is Outcome.UNCHANGED and effects == []  # on its last leg: nothing left
    other = ((0.0, -2.1), (2.0, 0.0))
    effects = applied(ledger, TaskDecision("t1", "r1", "keep", "cw", revision=0, route=other))
    (sent,) = [e.message for e in effects if isinstance(e, Publish)]
    assert isinstance(sent, ParkAssignment) and sent.revision == 1
    assert [tuple(p) for p in sent.route] == list(other)
    straight = TaskDecision("t1", "r1", "keep", "cw", revision=1, route=())
    assert kinds(applied(ledger, straight))[-1] == "publish:park"  # straight on: a revision
    assert ledger.active["t1"].route == []
