"""The planner's contract: snapshot in, decisions out (assignment, law, hold with reason)."""

from __future__ import annotations

import math
from dataclasses import replace

from fleet.core.params import Tolerance
from fleet.core.planner import PlanningSnapshot, RobotSnapshot, TaskSnapshot, plan
from fleet.core.tasks import DEFAULT_GAINS, RobotStatus, TaskStatus
from fleet.core.types import Posture

TOL = Tolerance(position=0.1, heading=0.1)


def robot(rid: str, pose: Posture) -> RobotSnapshot:
    return RobotSnapshot(rid, pose, RobotStatus.IDLE, available=True)


def task(tid: str, goal: Posture, created: float, named: str | None = None) -> TaskSnapshot:
    return TaskSnapshot(
        task_id=tid,
        goal=goal,
        direction="auto",
        gains=dict(DEFAULT_GAINS),
        tolerance=TOL,
        status=TaskStatus.QUEUED,
        created_at=created,
        named_robot=named,
    )


def swap(separation: float) -> PlanningSnapshot:
    return PlanningSnapshot(
        version=7,
        robots=(robot("a", (-3.0, 0.0, 0.0)), robot("b", (3.0, 0.0, math.pi))),
        tasks=(task("ta", (3.0, 0.0, 0.0), 1.0, "a"), task("tb", (-3.0, 0.0, math.pi), 2.0, "b")),
        separation_m=separation,
        control_dt=0.05,
    )


def test_a_safe_swap_assigns_both_named_robots_with_a_law_and_no_hold() -> None:
    result = plan(swap(0.5))
    assert result.snapshot_version == 7 and result.safe
    by_task = {d.task_id: d for d in result.decisions}
    assert {t: (d.robot_id, d.action, d.hold) for t, d in by_task.items()} == {
        "ta": ("a", "assign", False),
        "tb": ("b", "assign", False),
    }
    assert result.min_separation_m >= 0.5 and result.waiting == 0


def test_when_no_option_is_safe_the_new_robots_hold_with_the_reason() -> None:
    result = plan(swap(5.0))  # no way round keeps 5 m on a 6 m swap
    assert not result.safe and result.waiting == 2
    for d in result.decisions:
        assert d.action == "assign" and d.hold
        assert d.reason is not None and "waiting" in d.reason


def test_nothing_to_plan_without_an_available_robot() -> None:
    snapshot = swap(0.5)
    busy = tuple(
        RobotSnapshot(r.robot_id, r.pose, RobotStatus.DRIVING, available=False)
        for r in snapshot.robots
    )
    result = plan(PlanningSnapshot(version=1, robots=busy, tasks=snapshot.tasks))
    assert result.decisions == () and result.safe


def test_a_task_taken_from_a_stuck_robot_goes_to_another_one_and_keeps_its_revision() -> None:
    near, far = robot("near", (2.0, 0.0, 0.0)), robot("far", (-4.0, 4.0, 0.0))
    requeued = replace(task("t", (4.0, 0.0, 0.0), 1.0), revision=3)
    snapshot = PlanningSnapshot(version=1, robots=(near, far), tasks=(requeued,), control_dt=0.05)
    (first,) = plan(snapshot).decisions
    assert (first.robot_id, first.revision) == ("near", 3)  # the nearer robot is cheaper
    avoiding = replace(requeued, avoid_robot="near")
    (moved,) = plan(replace(snapshot, tasks=(avoiding,))).decisions
    assert (moved.robot_id, moved.action, moved.revision) == ("far", "assign", 3)
    alone = replace(snapshot, robots=(near,), tasks=(avoiding,))
    (back,) = plan(alone).decisions  # no other robot: it goes back rather than wait for ever
    assert back.robot_id == "near"
