"""Stuck robots: detection with the cause, recoveries in order (flip, wait, requeue to
another robot) each stored in the task's history and counted, then failure."""

from __future__ import annotations

import math
from collections.abc import Iterator
from itertools import pairwise

import pytest

from fleet.core.geometry import segments_cross
from fleet.core.params import Avoidance, Gains
from fleet.core.planner import Plan, PlanningSnapshot, plan
from fleet.core.tasks import RobotStatus, RobotView, Task, TaskStatus
from fleet.core.wire import Obstacle, Pose, RobotMode
from fleet.service.stuck import StuckWatch, remaining, stuck_cause
from tests.fleet.service.conftest import Fleet, req

WINDOW = 30.0


def test_progress_restarts_the_window_and_holding_is_not_being_stuck() -> None:
    watch = StuckWatch(10.0)
    goal = Pose(x=5, y=0)
    watch.start("t", 0.0)
    watch.observe("t", Pose(x=0, y=0), goal, 1.0, held=False)
    watch.observe("t", Pose(x=1, y=0), goal, 9.0, held=False)  # progress: window restarts
    assert not watch.stuck("t", 18.0) and watch.stuck("t", 19.0)
    watch.observe("t", Pose(x=1, y=0), goal, 19.5, held=True)  # waiting on purpose
    assert not watch.stuck("t", 29.0)
    assert [watch.next_recovery("t", 30.0) for _ in range(4)] == ["flip", "wait", "requeue", None]
    assert remaining(Pose(x=0, y=0, theta=0.0), Pose(x=0, y=0, theta=3.0), 0.2) == pytest.approx(
        0.6
    )


def test_the_window_runs_on_the_robots_clock_too() -> None:
    """A robot whose clock runs five times the service's (a time-scaled simulation) is
    stuck after the window of its own driving; held, it is not; progress restarts it."""
    watch = StuckWatch(10.0)
    goal = Pose(x=5, y=0)
    watch.start("t", 0.0)
    for k in range(12):  # the service's 0..2.2 s, the robot's 0..11 s, standing
        watch.observe("t", Pose(x=0, y=0), goal, 0.2 * k, held=False, robot_t=1.0 * k)
    assert watch.stuck("t", 2.2)
    watch.start("t", 2.2)
    watch.observe("t", Pose(x=0, y=0), goal, 2.4, held=True, robot_t=12.0)
    watch.observe("t", Pose(x=0, y=0), goal, 4.8, held=True, robot_t=24.0)
    assert not watch.stuck("t", 4.8)
    watch.observe("t", Pose(x=0, y=0), goal, 5.0, held=False, robot_t=25.0)
    watch.observe("t", Pose(x=1, y=0), goal, 6.0, held=False, robot_t=30.0)  # progress
    watch.observe("t", Pose(x=1, y=0), goal, 7.8, held=False, robot_t=39.0)
    assert not watch.stuck("t", 7.8)
    watch.observe("t", Pose(x=1, y=0), goal, 8.0, held=False, robot_t=40.0)
    assert watch.stuck("t", 8.0)
    assert watch.next_recovery("t", 8.0) == "flip"
    watch.observe("t", Pose(x=1, y=0), goal, 8.2, held=False, robot_t=41.0)
    assert not watch.stuck("t", 8.2)  # a fresh window after a recovery


def test_the_cause_is_what_the_service_can_see() -> None:
    me = RobotView(robot_id="a", status=RobotStatus.DRIVING, pose=Pose(x=0, y=0), last_seen=0)
    peer = me.model_copy(update={"robot_id": "b", "pose": Pose(x=0.7, y=0)})
    pillar = Obstacle(x=0.5, y=0.5, radius=1.0)
    assert stuck_cause(me, False, [me, peer], [pillar], 1.0, 30) == "a peer in the way: b at 0.70 m"
    assert stuck_cause(me, False, [me], [pillar], 1.0, 30).startswith("an obstacle in the way")
    assert (
        stuck_cause(me, True, [me], [], 1.0, 30) == "no pose: nothing heard from the robot for 30 s"
    )
    assert stuck_cause(me, False, [me], [], 1.0, 30).startswith("no progress for 30 s")
    stale = me.model_copy(update={"status": RobotStatus.HOLDING, "detail": "pose stale"})
    assert (
        stuck_cause(stale, False, [stale], [], 1.0, 30) == "no pose: the robot's own pose is stale"
    )


class RecordingPlanner:
    """The real planner, keeping the snapshots it was given."""

    def __init__(self) -> None:
        self.snapshots: list[PlanningSnapshot] = []

    def __call__(self, snapshot: PlanningSnapshot) -> Plan:
        self.snapshots.append(snapshot)
        return plan(snapshot)


@pytest.fixture
def planner() -> RecordingPlanner:
    return RecordingPlanner()


@pytest.fixture
def fleet(planner: RecordingPlanner) -> Iterator[Fleet]:
    f = Fleet(planner=planner, task_timeout_s=1000.0, stuck_after_s=WINDOW)
    yield f
    f.service.close()


def test_a_stuck_task_is_flipped_then_delayed_then_requeued_to_another_robot_then_failed(
    fleet: Fleet, planner: RecordingPlanner
) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(5.0, 0.0))
    fleet.service.tick()
    assigned = fleet.service.task(task.id)
    assert assigned.robot_id == "r1"
    fleet.join("r2", -0.8, 0.0)  # a robot stops right by r1 (farther from the goal)

    def stand_still(rid: str, revision: int, seconds: float = WINDOW) -> None:
        for _ in range(3):
            fleet.robot(rid, 0.0, 0.0, mode=RobotMode.DRIVING, task_id=task.id, revision=revision)
            fleet.clock.advance(seconds / 2)
        fleet.service.tick()

    stand_still("r1", 0)
    # the recovery holds the robot with the other law; the plan it asks for resumes it
    # (a checked plan, the flipped law kept)
    held, resumed = fleet.parks("r1")[-2:]
    assert (held.revision, held.hold, held.law) == (1, True, resumed.law)
    assert (resumed.revision, resumed.hold) == (2, False) and resumed.law != assigned.law
    flipped = fleet.service.task(task.id)
    assert (flipped.law, flipped.revision) == (resumed.law, 2)
    (recovery,) = [t for _, e, t in fleet.service.history(task.id) if e == "recovery"]
    assert recovery.reason == "stuck: a peer in the way: r2 at 0.80 m; recovery 1: flip"
    (seen,) = [t for t in planner.snapshots[-1].tasks if t.task_id == task.id]
    assert seen.direction == resumed.law  # pinned: the planner may only use the flipped law

    stand_still("r1", 2)
    held, resumed = fleet.parks("r1")[-2:]
    assert (held.revision, held.hold) == (3, True) and resumed.revision == 4
    waited = fleet.service.task(task.id)
    assert waited.law == flipped.law and waited.revision == 4

    fleet.robot("r2", 0.0, 4.0)  # the peer moved on, out of r1's way
    stand_still("r1", 4)
    fleet.service.tick()  # planned: to the other robot, although r1 is free again
    (seen,) = [t for t in planner.snapshots[-1].tasks if t.task_id == task.id]
    assert seen.avoid_robot == "r1"  # a planner input: give it to another robot if any
    moved = fleet.service.task(task.id)
    assert moved.robot_id == "r2" and moved.status is TaskStatus.ASSIGNED
    assert moved.attempts == 2 and moved.revision == 5  # a requeue is a new revision
    assert fleet.cancels("r1")[-1].task_id == task.id

    for _ in range(3):
        fleet.robot("r2", 0.0, 4.0, mode=RobotMode.DRIVING, task_id=task.id, revision=5)
        fleet.clock.advance(WINDOW / 2)
    fleet.service.tick()
    failed = fleet.service.task(task.id)
    assert failed.status is TaskStatus.FAILED
    assert failed.reason is not None and failed.reason.endswith("3 recoveries did not help")
    events = [event for _, event, _ in fleet.service.history(task.id)]
    assert events.count("recovery") == 3
    assert fleet.service.counters["recoveries"] == 3 and fleet.service.counters["stuck"] == 4


def test_a_robot_stuck_on_its_route_is_flipped_off_it_to_the_laws_own_way(
    fleet: Fleet, planner: RecordingPlanner
) -> None:
    """Where Eq. (27) holds a robot off a via-point, another law on the same route does
    not help: the flip takes it off the route until it arrives or is requeued."""
    fleet.service.set_obstacles([Obstacle(x=2.5, y=-1.5, end=(2.5, 1.5), radius=0.3, body=0.05)])
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(5.0, 0.0))
    fleet.service.tick()
    routed = fleet.service.task(task.id)
    assert routed.robot_id == "r1" and routed.route  # round the post

    for _ in range(3):
        fleet.robot("r1", 0.0, 0.0, mode=RobotMode.DRIVING, task_id=task.id, revision=0)
        fleet.clock.advance(WINDOW / 2)
    fleet.service.tick()
    held, resumed = fleet.parks("r1")[-2:]
    assert held.hold and (resumed.hold, resumed.route) == (False, [])
    (recovery,) = [t for _, e, t in fleet.service.history(task.id) if e == "recovery"]
    assert recovery.reason is not None and recovery.reason.endswith(
        "recovery 1: flip (off its route: the law's own way)"
    )
    (seen,) = [t for t in planner.snapshots[-1].tasks if t.task_id == task.id]
    assert seen.own_way and seen.direction == resumed.law
    assert fleet.service.task(task.id).route == []


def test_a_standoff_is_avoiding_without_progress_on_the_robots_own_clock() -> None:
    watch = StuckWatch(1000.0, standoff_after_s=4.0)
    goal = Pose(x=5, y=0)
    here = Pose(x=0, y=0)
    watch.start("t", 0.0)
    watch.observe("t", here, goal, 0.0, held=False, robot_t=10.0, avoiding=True)
    watch.observe("t", here, goal, 0.0, held=False, robot_t=13.9, avoiding=True)
    assert not watch.standoff("t")  # service time stood still: robot time is what counts
    watch.observe("t", here, goal, 0.0, held=False, robot_t=14.0, avoiding=True)
    assert watch.standoff("t")
    watch.observe("t", here, goal, 0.0, held=False, robot_t=14.1, avoiding=False)
    assert not watch.standoff("t")  # driving, not held off by anything: not a standoff
    watch.observe("t", here, goal, 0.0, held=False, robot_t=14.2, avoiding=True)
    assert watch.standoff("t")
    watch.restart("t")  # another robot gave way
    assert not watch.standoff("t")
    watch.observe("t", Pose(x=0.2, y=0), goal, 0.0, held=False, robot_t=20.0, avoiding=True)
    assert not watch.standoff("t")  # progress restarts the window
    watch.observe("t", Pose(x=0.2, y=0), goal, 0.0, held=False, robot_t=1.0, avoiding=True)
    watch.observe("t", Pose(x=0.2, y=0), goal, 0.0, held=False, robot_t=4.5, avoiding=True)
    assert not watch.standoff("t")  # the robot restarted (its clock went back): a new window
    watch.observe("t", Pose(x=0.2, y=0), goal, 0.0, held=False, robot_t=5.0, avoiding=True)
    assert watch.standoff("t")


def test_a_robot_creeping_a_few_centimetres_at_a_time_is_still_in_a_standoff() -> None:
    """Held off by a peer, a robot dithers and creeps (6 cm a second here, 4 cm per state):
    less than ``standoff_progress_m`` in the window is no way out; more is progress."""
    watch = StuckWatch(1000.0, standoff_after_s=4.0, standoff_progress_m=0.3)
    goal = Pose(x=5, y=0)
    watch.start("t", 0.0)
    for k in range(7):  # 0.24 m in 4 s
        at = Pose(x=0.04 * k, y=0)
        watch.observe("t", at, goal, 0.0, held=False, robot_t=10.0 + 4.0 * k / 6, avoiding=True)
    assert watch.standoff("t")
    creeping = StuckWatch(1000.0, standoff_after_s=4.0)  # 5 cm of progress, the old rule
    creeping.start("t", 0.0)
    for k in range(7):
        at = Pose(x=0.06 * k, y=0)
        creeping.observe("t", at, goal, 0.0, held=False, robot_t=10.0 + 4.0 * k / 6, avoiding=True)
    assert not creeping.standoff("t")
    watch.restart("t")
    watch.observe("t", Pose(x=0.6, y=0), goal, 0.0, held=False, robot_t=15.0, avoiding=True)
    watch.observe("t", Pose(x=1.0, y=0), goal, 0.0, held=False, robot_t=18.9, avoiding=True)
    watch.observe("t", Pose(x=1.0, y=0), goal, 0.0, held=False, robot_t=22.0, avoiding=True)
    assert not watch.standoff("t")  # 0.4 m at 18.9 s restarted the window


def test_in_a_standoff_the_younger_task_gives_way_with_the_other_law_until_a_plan() -> None:
    """The younger task's robot holds with the other law; the plans see that it gave way
    (the others are routed round it) until one resumes it."""
    from fleet.core.planner import TaskDecision
    from fleet.core.wire import RobotState
    from tests.fleet.service.conftest import ScriptedPlanner, assign_queued

    planner = ScriptedPlanner(assign_queued("ccw"))
    f = Fleet(planner=planner, task_timeout_s=1000.0)
    try:
        f.join("old", -0.3, 0.0)
        f.join("new", 0.3, 0.0)
        f.join("far", 5.0, 5.0)
        first = f.service.submit(req(4.0, 0.0, robot="old"))
        f.clock.advance(1.0)
        second = f.service.submit(req(-4.0, 0.0, robot="new"))
        third = f.service.submit(req(5.0, -3.0, robot="far"))
        f.service.tick()

        def states(seq: int) -> None:
            for rid, x, task in (("old", -0.3, first), ("new", 0.3, second), ("far", 5.0, third)):
                f.bus.deliver_state(
                    RobotState(robot_id=rid, seq=seq, stamp=f.clock.wall(),
                               pose=Pose(x=x, y=0.0 if rid != "far" else 5.0),
                               mode=RobotMode.AVOIDING, task_id=task.id, revision=0)
                )  # fmt: skip

        states(100)  # nose to nose, both avoiding, no progress; "far" avoids alone
        states(499)
        f.service.tick()
        assert f.service.counters.get("standoffs_broken", 0) == 0  # 7.98 s: not yet
        states(500)  # 8 s of the robots' own time (50 Hz)
        f.service.tick()
        assert f.service.counters["standoffs_broken"] == 1
        gave = f.service.task(second.id)
        assert gave.hold and gave.law == "cw" and gave.revision == 1
        assert gave.reason is not None and gave.reason.startswith(
            "standoff: no progress for 8 s while avoiding old at 0.60 m; gives way (cw)"
        )
        assert not f.service.task(first.id).hold and f.service.task(first.id).revision == 0
        assert not f.service.task(third.id).hold  # alone, no post near: the stuck watch's
        (held,) = [p for p in f.parks("new") if p.revision == 1]
        assert held.hold and held.law == "cw"
        assert [e for _, e, _ in f.service.history(second.id)][-1] == "standoff"

        def gave_way() -> set[str]:
            f.clock.advance(5.0)
            f.service.tick()  # the periodic plan
            return {t.task_id for t in planner.snapshots[-1].tasks if t.gave_way}

        assert gave_way() == {second.id}  # the plan routes "old" round it while it stands
        planner.decide = lambda snapshot: [
            TaskDecision(t.task_id, t.robot_id, "revise", t.law, revision=t.revision)
            for t in snapshot.tasks
            if t.hold and t.robot_id is not None and t.law is not None
        ]
        f.clock.advance(5.0)
        f.service.tick()  # a plan resumes it
        assert not f.service.task(second.id).hold
        assert gave_way() == set()
    finally:
        f.service.close()


def test_a_robot_held_off_by_a_standing_robot_is_routed_round_it_not_made_to_give_way() -> None:
    """A standoff's robot is held off by a robot that stands with no task (parked, idle):
    giving way to it changes nothing (seen on case III with four robots: the last robot
    stood off against two parked ones). The plans route the mover round that robot
    (``round_robots``) and its window restarts; a second standoff against the same robot
    is broken the usual way (it gives way)."""
    from fleet.core.wire import RobotState
    from tests.fleet.service.conftest import ScriptedPlanner, assign_queued

    planner = ScriptedPlanner(assign_queued("ccw"))
    f = Fleet(planner=planner, task_timeout_s=1000.0)
    try:
        f.join("mover", -0.3, 0.0)
        f.join("parked", 0.4, 0.0)
        moving = f.service.submit(req(4.0, 0.0, robot="mover"))
        f.service.tick()

        def states(seq: int) -> None:
            f.bus.deliver_state(
                RobotState(robot_id="mover", seq=seq, stamp=f.clock.wall(),
                           pose=Pose(x=-0.3, y=0.0), mode=RobotMode.AVOIDING,
                           task_id=moving.id, revision=f.service.task(moving.id).revision)
            )  # fmt: skip

        def round_robots() -> tuple[str, ...]:
            f.clock.advance(5.0)
            f.service.tick()  # the plan the standoff asked for
            (task,) = [t for t in planner.snapshots[-1].tasks if t.task_id == moving.id]
            return task.round_robots

        states(100)
        assert round_robots() == ()
        states(500)  # 8 s of the mover's own time without progress
        f.service.tick()
        assert f.service.counters["standoffs_broken"] == 1
        assert not f.service.task(moving.id).hold  # it did not give way
        assert "standoff" not in [e for _, e, _ in f.service.history(moving.id)]
        assert round_robots() == ("parked",)
        states(900)
        states(1300)  # 8 s more, still held off by the same robot
        f.service.tick()
        assert f.service.counters["standoffs_broken"] == 2
        assert f.service.task(moving.id).hold  # now it gives way, the usual way
        assert [e for _, e, _ in f.service.history(moving.id)][-1] == "standoff"
    finally:
        f.service.close()


def test_a_robot_held_off_by_one_waiting_for_its_zone_has_that_one_stand_aside() -> None:
    """A standoff's robot is held off by a robot the plan holds until a zone the first
    holds is free: giving way would wait for a robot that waits for it (a loop seen on
    case III with four robots: a give-way every 8 s for 100 s). The waiting robot stands
    aside instead -- the plan routes the other round it, as round one that gave way --; a
    second standoff of the pair is broken the usual way. Held for anything else (no zone
    of the other's), the other gives way at once."""
    from fleet.core.planner import TaskDecision
    from fleet.core.site import Wall
    from fleet.core.wire import RobotState
    from fleet.core.zones import ZonePass
    from tests.fleet.service.conftest import ScriptedPlanner

    corridor = Wall(
        points=[(-10, 5), (-4, 5), (-4, 0.6), (4, 0.6), (4, 5), (10, 5), (10, -5), (4, -5),
                (4, -0.6), (-4, -0.6), (-4, -5), (-10, -5)],
        closed=True, body=0.05,
    ).segments()  # fmt: skip

    def run(waits_for: str | None) -> tuple[Fleet, Task, Task, ScriptedPlanner]:
        def decide(snapshot: PlanningSnapshot) -> list[TaskDecision]:
            through = ZonePass("passage-1", (-4.0, 0.0), (4.0, 0.0))
            return [
                TaskDecision(
                    t.task_id,
                    t.named_robot or "",
                    "assign",
                    "cw",
                    hold=t.named_robot == "held",
                    waits_for=waits_for if t.named_robot == "held" else None,
                    zones=(through,) if t.named_robot == "mover" else (),
                )
                for t in snapshot.tasks
                if t.status is TaskStatus.QUEUED
            ]

        planner = ScriptedPlanner(decide)
        f = Fleet(planner=planner, task_timeout_s=1000.0, yard=(-11.0, 11.0, -6.0, 6.0))
        f.service.set_obstacles(corridor)
        f.join("mover", -0.3, 0.0)
        f.join("held", 0.3, 0.0)
        moving = f.service.submit(req(7.0, 2.5, robot="mover"))
        waiting = f.service.submit(req(-7.0, -2.5, robot="held"))
        f.service.tick()
        return f, moving, waiting, planner

    def started(f: Fleet, moving: Task, waiting: Task) -> None:
        (passage,) = f.service.zones()
        assert passage.robot_ids == ("mover", "held")  # "held" stands in it
        assert f.service.task(waiting.id).hold and not f.service.task(moving.id).hold

    def states(f: Fleet, moving: Task, waiting: Task, seq: int) -> None:
        for rid, x, task, mode in (
            ("mover", -0.3, moving, RobotMode.AVOIDING),
            ("held", 0.3, waiting, RobotMode.WAITING),
        ):
            f.bus.deliver_state(
                RobotState(robot_id=rid, seq=seq, stamp=f.clock.wall(),
                           pose=Pose(x=x, y=0.0), mode=mode, task_id=task.id,
                           revision=f.service.task(task.id).revision)
            )  # fmt: skip

    f, moving, waiting, planner = run("passage-1")
    try:
        started(f, moving, waiting)
        states(f, moving, waiting, 100)
        states(f, moving, waiting, 500)  # 8 s of the mover's own time without progress
        f.service.tick()
        assert f.service.counters["standoffs_broken"] == 1
        assert not f.service.task(moving.id).hold  # it did not give way
        assert "standoff" not in [e for _, e, _ in f.service.history(moving.id)]
        f.clock.advance(5.0)
        f.service.tick()  # the plan the standoff asked for
        assert {t.task_id for t in planner.snapshots[-1].tasks if t.gave_way} == {waiting.id}
        states(f, moving, waiting, 900)
        states(f, moving, waiting, 1300)  # 8 s more, still held off
        f.service.tick()
        assert f.service.task(moving.id).hold  # now it gives way, the usual way
        assert [e for _, e, _ in f.service.history(moving.id)][-1] == "standoff"
    finally:
        f.service.close()
    f, moving, waiting, planner = run(None)  # held, but for no zone of the mover's
    try:
        started(f, moving, waiting)
        states(f, moving, waiting, 100)
        states(f, moving, waiting, 500)
        f.service.tick()
        assert f.service.task(moving.id).hold
        assert [e for _, e, _ in f.service.history(moving.id)][-1] == "standoff"
    finally:
        f.service.close()


def test_a_robot_alone_by_posts_gets_only_its_first_stuck_recovery_early() -> None:
    """In the mouth of the gap between case III's posts, no robot near, without progress
    for ``post_stall_after_s`` (3 s of its own time, not the standoff's 8): the first
    stuck recovery comes then (routed round the posts' zones); a robot alone away from
    the posts stalled as long is left to the stuck watch; once resumed, standing as long
    again is not another early recovery (the later ones wait for the whole window)."""
    from fleet.core.planner import TaskDecision
    from fleet.core.wire import RobotState
    from tests.fleet.service.conftest import ScriptedPlanner

    def decide(snapshot: PlanningSnapshot) -> list[TaskDecision]:
        out = []
        for t in snapshot.tasks:  # assign queued tasks, resume held ones
            if t.status is TaskStatus.QUEUED:
                out.append(TaskDecision(t.task_id, "alone", "assign", "cw"))
            elif t.hold and t.robot_id is not None and t.law is not None:
                out.append(TaskDecision(t.task_id, t.robot_id, "revise", t.law,
                                        revision=t.revision))  # fmt: skip
        return out

    f = Fleet(planner=ScriptedPlanner(decide), task_timeout_s=1000.0)
    try:
        f.service.set_obstacles([Obstacle(x=x, y=0.0, radius=1.0, body=0.2) for x in (0.8, -0.8)])
        f.join("alone", 0.0, 0.5)
        f.join("afield", 6.0, 6.0)
        task = f.service.submit(req(0.0, -2.0, robot="alone"))
        afield = f.service.submit(req(6.0, 3.0, robot="afield"))
        f.service.tick()

        def state(seq: int) -> None:
            for rid, (x, y), t in (("alone", (0.0, 0.5), task), ("afield", (6.0, 6.0), afield)):
                f.bus.deliver_state(
                    RobotState(robot_id=rid, seq=seq, stamp=f.clock.wall(),
                               pose=Pose(x=x, y=y), mode=RobotMode.AVOIDING,
                               task_id=t.id, revision=f.service.task(t.id).revision)
                )  # fmt: skip

        state(100)
        state(249)  # 2.98 s of its own time (50 Hz), not a metre nearer
        f.service.tick()
        assert "recovery" not in [e for _, e, _ in f.service.history(task.id)]
        state(250)  # 3 s
        f.service.tick()
        assert "recovery" not in [e for _, e, _ in f.service.history(afield.id)]
        (recovery,) = [t for _, e, t in f.service.history(task.id) if e == "recovery"]
        assert recovery.reason is not None and recovery.reason.endswith(
            "recovery 1: flip (routed round the posts' Eq. (27) zones)"
        )
        f.service.tick()  # the plan resumes it
        assert not f.service.task(task.id).hold
        for seq in (600, 800, 1000, 1100):  # 8 s more, resumed, still no progress
            state(seq)
            f.service.tick()
        assert [e for _, e, _ in f.service.history(task.id)].count("recovery") == 1
        assert f.service.counters["recoveries"] == 1
    finally:
        f.service.close()


def test_a_robot_stuck_by_posts_without_a_route_is_routed_round_their_zones(
    fleet: Fleet, planner: RecordingPlanner
) -> None:
    """The paper's case III pair: in the gap's mouth both posts' Eq. (27) terms hold a
    robot facing through it; the flip routes it round the pair's zones, not through them."""
    posts = [Obstacle(x=x, y=0.0, radius=1.0, body=0.2) for x in (0.8, -0.8)]
    fleet.service.set_obstacles(posts)
    fleet.join("r1", 0.0, 0.5)
    fleet.robot("r1", 0.0, 0.5, -math.pi / 2)
    task = fleet.service.submit(req(0.0, -2.0))
    fleet.service.tick()
    assigned = fleet.service.task(task.id)
    assert assigned.robot_id == "r1" and assigned.route == []  # straight through the gap

    for _ in range(3):
        fleet.robot("r1", 0.0, 0.5, -math.pi / 2, mode=RobotMode.DRIVING, task_id=task.id)
        fleet.clock.advance(WINDOW / 2)
    fleet.service.tick()
    (recovery,) = [t for _, e, t in fleet.service.history(task.id) if e == "recovery"]
    assert recovery.reason is not None and recovery.reason.endswith(
        "recovery 1: flip (routed round the posts' Eq. (27) zones)"
    )
    (seen,) = [t for t in planner.snapshots[-1].tasks if t.task_id == task.id]
    assert seen.wide_way and not seen.own_way
    held, resumed = fleet.parks("r1")[-2:]
    assert held.hold and not resumed.hold and resumed.route
    way = [(0.0, 0.5), *resumed.route, (0.0, -2.0)]
    assert not any(segments_cross(a, b, (-0.8, 0.0), (0.8, 0.0)) for a, b in pairwise(way))


@pytest.fixture
def narrow_bands_fleet(planner: RecordingPlanner) -> Iterator[Fleet]:
    """The fleet above with Eq. (27)'s bands 0.25 m wide (the default before 0.6 m): its
    planner sends the robot of the next test through case III's gap on a route (with the
    wider bands it sends it without one)."""
    f = Fleet(
        planner=planner,
        task_timeout_s=1000.0,
        stuck_after_s=WINDOW,
        avoidance=Avoidance(smoothing_m=0.25),
    )
    yield f
    f.service.close()


@pytest.mark.parametrize("peer_near", [False, True], ids=["alone", "a-peer-near"])
def test_a_robot_stuck_by_posts_on_a_route_through_their_gap_goes_round_their_zones_when_alone(
    narrow_bands_fleet: Fleet, planner: RecordingPlanner, peer_near: bool
) -> None:
    """A route through the case III pair's gap, the robot held in the gap's mouth facing
    the via-point: leaving the route for the law's own way leaves it in the mouth (a
    benchmark run circled there for 100 s); the flip routes it round the pair's zones --
    when it is alone: robots near each other sent round the posts meet again there, so
    with a peer near it leaves its route for the law's own way."""
    fleet = narrow_bands_fleet
    posts = [Obstacle(x=x, y=0.0, radius=1.0, body=0.2) for x in (0.8, -0.8)]
    fleet.service.set_obstacles(posts)
    fleet.join("r1", -0.5, 1.3)
    fleet.robot("r1", -0.5, 1.3, -math.pi / 3)
    gains = {"ccw": Gains(kx=0.6, ky=2.9, ktheta=2.4), "cw": Gains(kx=2.0, ky=6.0, ktheta=6.0)}
    task = fleet.service.submit(req(0.0, -2.0, direction="cw", law_gains=gains))  # Table 8's
    fleet.service.tick()
    routed = fleet.service.task(task.id)
    assert routed.robot_id == "r1" and routed.route
    first = [(-0.5, 1.3), *routed.route]
    assert any(segments_cross(a, b, (-0.8, 0.0), (0.8, 0.0)) for a, b in pairwise(first))
    mouth = (-0.13, 0.62)
    if peer_near:
        fleet.join("r2", -0.13, 1.42)  # 0.8 m behind it, idle
    for _ in range(3):
        fleet.robot("r1", *mouth, -math.pi / 2, mode=RobotMode.DRIVING, task_id=task.id)
        if peer_near:
            fleet.robot("r2", -0.13, 1.42)
        fleet.clock.advance(WINDOW / 2)
    fleet.service.tick()
    (recovery,) = [t for _, e, t in fleet.service.history(task.id) if e == "recovery"]
    (seen,) = [t for t in planner.snapshots[-1].tasks if t.task_id == task.id]
    held, resumed = fleet.parks("r1")[-2:]
    assert held.hold and not resumed.hold
    assert recovery.reason is not None
    if peer_near:
        assert recovery.reason.endswith("recovery 1: flip (off its route: the law's own way)")
        assert seen.own_way and not seen.wide_way and resumed.route == []
        return
    assert recovery.reason.endswith("recovery 1: flip (routed round the posts' Eq. (27) zones)")
    assert seen.wide_way and not seen.own_way and resumed.route
    way = [mouth, *resumed.route, (0.0, -2.0)]
    assert not any(segments_cross(a, b, (-0.8, 0.0), (0.8, 0.0)) for a, b in pairwise(way))
