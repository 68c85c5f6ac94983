"""A snapshot holding only the queued tasks ``plannable`` keeps pairs exactly as one with
every queued task (the fleet service sends the planner no others)."""

from __future__ import annotations

import dataclasses

from hypothesis import given, settings
from hypothesis import strategies as st
from planning import idle, queued

from fleet.core.planner import PlannerConfig, PlanningSnapshot, RobotSnapshot
from fleet.core.planner.assign import pair_queued, plannable
from fleet.core.tasks import TaskStatus

ROBOTS = ("r0", "r1", "r2", "r3")


def _trimmed(snapshot: PlanningSnapshot) -> PlanningSnapshot:
    """``snapshot`` with the queued tasks ``plannable`` leaves out left out (the service's
    rule, fleet/service/snapshot.py)."""
    available = {r.robot_id for r in snapshot.robots if r.available}
    waiting = sorted(
        (t for t in snapshot.tasks if t.status is TaskStatus.QUEUED), key=lambda t: t.created_at
    )
    kept = {t.task_id for t in plannable(waiting, available, lambda t: t.named_robot)}
    return dataclasses.replace(
        snapshot,
        tasks=tuple(
            t for t in snapshot.tasks if t.status is not TaskStatus.QUEUED or t.task_id in kept
        ),
    )


@st.composite
def yards(draw: st.DrawFn) -> PlanningSnapshot:
    """Up to 4 robots (some unavailable), up to 10 queued tasks, named or not, created at
    few distinct times (ties) and listed in any order."""
    coord = st.floats(-8.0, 8.0)
    robots: list[RobotSnapshot] = []
    for i, rid in enumerate(ROBOTS[: draw(st.integers(1, 4))]):
        robot = idle(rid, (3.0 * i - 4.0, -6.0, 1.57))
        robots.append(dataclasses.replace(robot, available=draw(st.booleans())))
    names = st.sampled_from([None, None, *(r.robot_id for r in robots), "gone"])
    tasks = [
        queued(
            f"t{k}", (draw(coord), draw(coord), 0.0), draw(names), float(draw(st.integers(0, 3)))
        )
        for k in range(draw(st.integers(0, 10)))
    ]
    return PlanningSnapshot(1, tuple(robots), tuple(draw(st.permutations(tasks))))


def _pairs(snapshot: PlanningSnapshot) -> list[tuple[str, str]]:
    return [(t.task_id, r.robot_id) for t, r in pair_queued(snapshot, PlannerConfig())]


@settings(max_examples=60, deadline=None)
@given(yards())
def test_the_trimmed_snapshot_pairs_the_same_tasks_with_the_same_robots(
    snapshot: PlanningSnapshot,
) -> None:
    trimmed = _trimmed(snapshot)
    available = sum(r.available for r in snapshot.robots)
    assert len(trimmed.tasks) <= 2 * available  # one named and one unnamed per robot at most
    assert _pairs(trimmed) == _pairs(snapshot)


def test_for_each_available_robot_its_oldest_task_and_as_many_unnamed_oldest_first() -> None:
    tasks = [("a", "r1"), ("b", None), ("c", "r1"), ("d", "r2"), ("e", None), ("f", None)]
    kept = plannable(tasks, {"r1", "r3"}, lambda t: t[1])
    assert [t[0] for t in kept] == ["a", "b", "e"]  # r1's oldest, then two unnamed; r2 busy


def test_nothing_is_plannable_without_an_available_robot() -> None:
    assert plannable([("a", None), ("b", "r1")], set(), lambda t: t[1]) == []
