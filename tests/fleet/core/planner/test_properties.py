"""Properties of the pure planner on random scenes (Hypothesis).

- Every robot a plan starts or resumes is safe in an independent replay of the plan, and
  arrives when the plan says; every hold carries a reason.
- A robot far away (its own cluster) does not change the other robots' decisions.
- The same snapshot gives the same plan; the scene re-planned a little later, with the
  robots where the plan took them, keeps every decision but the switching rule's flips
  near the goal, which never make the fleet later.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from planning import idle, moved_on, queued, replay, scene

from fleet.core.planner import Plan, PlannerConfig, PlanningSnapshot, plan
from fleet.core.types import Posture

SEP = 0.5
CELL = 1.6  # [m] grid of start and goal cells: points at least CELL - 2 * JITTER apart
JITTER = 0.2


@st.composite
def scenes(draw: st.DrawFn, most: int = 3) -> PlanningSnapshot:
    """2..``most`` robots, starts and goals on distinct cells of a 5 x 5 grid (jittered)."""
    n = draw(st.integers(2, most))
    cells = draw(st.lists(st.integers(0, 24), min_size=2 * n, max_size=2 * n, unique=True))
    jitter = st.floats(-JITTER, JITTER, allow_nan=False)
    heading = st.floats(-math.pi, math.pi, allow_nan=False)
    points: list[Posture] = []
    for c in cells:
        x = (c % 5 - 2) * CELL + draw(jitter)
        y = (c // 5 - 2) * CELL + draw(jitter)
        points.append((x, y, draw(heading)))
    return scene(points[:n], points[n:], separation=SEP)


def check_safe(snapshot: PlanningSnapshot, result: Plan) -> None:
    for d in result.decisions:
        assert not d.hold or (d.reason and d.reason.startswith("waiting"))
    horizon = max((d.corridor[-1][0] for d in result.decisions if d.corridor), default=0.0)
    run = replay(snapshot, result, max_time=horizon)
    assert run.worst_shortfall(snapshot.separation_m) <= 1e-9
    ids = [r.robot_id for r in snapshot.robots]
    for d in result.decisions:
        if d.predicted_arrival_s is not None:
            i = ids.index(d.robot_id)
            assert run.result.done[i]
            assert abs(float(run.result.time[i]) - d.predicted_arrival_s) < 1e-6


@settings(max_examples=12)
@given(scenes())
def test_every_robot_a_plan_moves_is_safe_in_an_independent_replay(s: PlanningSnapshot) -> None:
    result = plan(s)
    assert result.safe
    check_safe(s, result)


@settings(max_examples=8)
@given(scenes(), st.floats(-math.pi, math.pi))
def test_a_robot_far_away_does_not_change_the_others_decisions(
    s: PlanningSnapshot, heading: float
) -> None:
    far = dataclasses.replace(
        s,
        robots=(*s.robots, idle("far", (90.0, 90.0, heading))),
        tasks=(*s.tasks, queued("far-task", (94.0, 90.0, heading), "far", 99.0)),
    )
    alone, together = plan(s), plan(far)
    assert together.clusters == alone.clusters + 1
    assert together.decisions[: len(alone.decisions)] == alone.decisions
    assert together.decisions[-1].robot_id == "far"


#: Re-planned 1 s later, r2 (1.97 m from its goal) is 4 s sooner with its other law: the
#: switching rule flips it (it was the failing example the stricter property replayed).
_FLIP_NEAR_GOAL = scene(
    [(0.0, 1.6, 0.0), (1.6, 3.2, 0.0), (-1.6, 1.6, 0.0)],
    [(0.0, -1.6, -1.0), (-1.6, -3.2, 0.0), (0.0, 3.2, 0.0)],
    separation=SEP,
)
#: Re-planned 2.5 s later, r2 flips near its goal and r1, keeping its law, arrives sooner.
_FLIP_SPEEDS_A_PEER = scene(
    [(3.3, 1.53, 1.77), (1.74, 0.11, -0.83), (-0.02, -0.1, 1.34), (1.45, -1.5, -1.77)],
    [(-0.18, 3.23, -1.78), (-3.16, 1.76, 2.69), (-1.49, 1.6, 2.4), (-1.68, -3.18, -1.69)],
    separation=SEP,
)


@settings(max_examples=8)
@given(scenes(), st.sampled_from([0.0, 1.0, 2.5]))
@example(_FLIP_NEAR_GOAL, 1.0)
@example(_FLIP_SPEEDS_A_PEER, 2.5)
def test_decisions_are_stable(s: PlanningSnapshot, elapsed: float) -> None:
    """Re-planned ``elapsed`` s later with the robots where the plan took them, every
    decision is kept -- except the switching rule's flip of a robot within
    ``flip_within_m`` of its goal (``PlannerConfig.flip_gain_s``), which never makes the
    fleet later; without a flip every robot arrives when it was predicted to."""
    first = plan(s)
    assert plan(s) == first  # a pure function of the snapshot
    assume(first.waiting == 0 and first.min_separation_m > SEP + 0.02)
    arrivals = [d.predicted_arrival_s for d in first.decisions]
    assume(all(a is not None and a > elapsed + 1.0 for a in arrivals))
    moved = moved_on(s, first, elapsed)
    pose = {r.robot_id: r.pose for r in moved.robots}
    goal = {t.task_id: t.goal for t in moved.tasks}
    again = {d.task_id: d for d in plan(moved).decisions}
    assert sorted(again) == sorted(d.task_id for d in first.decisions)
    flipped = False
    for old in first.decisions:
        new = again[old.task_id]
        assert not new.hold and new.predicted_arrival_s is not None
        if new.law == old.law:
            assert new.action == "keep"
        else:
            flipped = True
            assert new.action == "revise"
            near = math.dist(pose[old.robot_id][:2], goal[old.task_id][:2])
            assert near <= PlannerConfig().flip_within_m
    ends = [d.predicted_arrival_s for d in again.values() if d.predicted_arrival_s is not None]
    assert max(ends) + elapsed <= max(a for a in arrivals if a is not None) + 0.1
    if not flipped:
        for old in first.decisions:
            new = again[old.task_id]
            assert old.predicted_arrival_s is not None and new.predicted_arrival_s is not None
            assert np.isclose(new.predicted_arrival_s + elapsed, old.predicted_arrival_s, atol=0.1)
