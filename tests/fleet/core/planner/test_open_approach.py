"""Open approaches (:class:`PlannerConfig`): a new robot that drives straight gets one
via-point on its goal's axis when alone it arrives sooner by it, and the plan takes it
only where the whole plan is cheaper with it and every robot arrives."""

from __future__ import annotations

import dataclasses
import math

import pytest
from planning import moved_on, replay, scene

from fleet.core.planner import PlannerConfig, plan
from fleet.core.types import Posture
from fleet.core.wire import Obstacle

OFF = PlannerConfig(open_approach_m=())
#: 12 m to a goal whose heading is 90 degrees from the robot's (a right-hand swap's first
#: robot): alone, either law reaches the goal's heading beside the goal and turns a whole
#: turn more (18 s), against 13 s through a point on the goal's axis.
START: Posture = (6.0, 0.0, 0.75 * math.pi)
GOAL: Posture = (-6.0, 0.0, 1.25 * math.pi)


def _on_axis(point: tuple[float, float], goal: Posture) -> tuple[float, float]:
    """(along, across) [m]: ``point`` in the goal's frame."""
    dx, dy = point[0] - goal[0], point[1] - goal[1]
    c, s = math.cos(goal[2]), math.sin(goal[2])
    return c * dx + s * dy, c * dy - s * dx


def test_a_robot_alone_approaches_along_its_goals_axis_and_arrives_sooner() -> None:
    snapshot = scene([START], [GOAL])
    (plain,) = plan(snapshot, OFF).decisions
    result = plan(snapshot)
    (d,) = result.decisions
    assert plain.route == () and len(d.route) == 1
    along, across = _on_axis(d.route[0], GOAL)
    assert across == pytest.approx(0.0, abs=1e-9)
    assert -along in [pytest.approx(a) for a in PlannerConfig().open_approach_m]
    assert d.predicted_arrival_s is not None and plain.predicted_arrival_s is not None
    assert d.predicted_arrival_s < plain.predicted_arrival_s - PlannerConfig().open_approach_gain_s
    assert any("open approaches: 1" in n for n in result.notes)
    run = replay(snapshot, result)  # the robot drives the route as the plan predicts
    assert run.result.done.all()
    assert float(run.result.time[0]) == pytest.approx(d.predicted_arrival_s, abs=0.05)


def test_robots_that_would_meet_at_their_approach_points_keep_the_laws_way_round() -> None:
    """Four robots swapping across a circle: each alone would take its approach point, but
    driving straight at them all four meet in the middle, where the laws' rotation senses
    take them round each other: the plan is the plain one."""
    starts = [(6 * math.cos(a), 6 * math.sin(a), a + 0.75 * math.pi) for a in _quarters()]
    goals = [(-x, -y, t + 0.5 * math.pi) for x, y, t in starts]
    for start, goal in zip(starts, goals, strict=True):
        (alone,) = plan(scene([start], [goal])).decisions
        assert len(alone.route) == 1
    snapshot = scene(starts, goals)
    result, plain = plan(snapshot), plan(snapshot, OFF)
    assert all(d.route == () for d in result.decisions)
    assert result.decisions == plain.decisions
    assert not any("open approaches" in n for n in result.notes)


def _quarters() -> list[float]:
    return [k * math.pi / 2 for k in range(4)]


@pytest.mark.parametrize("behind", [0.9, -3.0], ids=["too-near", "past-the-goal"])
def test_no_approach_point_for_a_robot_near_or_past_its_goal(behind: float) -> None:
    """Within an approach distance + ``pass_m`` behind its goal (or in front of it), a
    robot would reach its goal before passing the point."""
    c, s = math.cos(GOAL[2]), math.sin(GOAL[2])
    start = (GOAL[0] - behind * c + 0.4 * s, GOAL[1] - behind * s - 0.4 * c, GOAL[2] + 2.0)
    (d,) = plan(scene([start], [GOAL])).decisions
    assert d.route == ()


def test_no_approach_point_whose_leg_passes_a_post() -> None:
    """A post 0.8 m beside the straight way (clear) but on both approach points' legs:
    the robot drives straight."""
    post = Obstacle(x=-5.2, y=0.8, radius=0.3, body=0.2)
    snapshot = dataclasses.replace(scene([START], [GOAL]), obstacles=(post,))
    (d,) = plan(snapshot).decisions
    assert d.route == ()


def test_a_robot_under_way_keeps_its_approach_point_until_it_passes_it() -> None:
    snapshot = scene([START], [GOAL])
    first = plan(snapshot)
    (d0,) = first.decisions
    assert len(d0.route) == 1 and d0.predicted_arrival_s is not None
    (kept,) = plan(moved_on(snapshot, first, 2.0)).decisions
    assert (kept.action, kept.law, kept.route) == ("keep", d0.law, d0.route)
    assert kept.predicted_arrival_s == pytest.approx(d0.predicted_arrival_s - 2.0, abs=0.1)
    (last,) = plan(moved_on(snapshot, first, d0.predicted_arrival_s - 0.5)).decisions
    assert last.route == () and last.action == "keep"


@pytest.mark.parametrize("value", [(0.0,), (-1.0,), (math.nan,), (math.inf,)])
def test_an_approach_distance_not_positive_and_finite_is_refused(value: tuple[float]) -> None:
    with pytest.raises(ValueError, match="open_approach_m"):
        PlannerConfig(open_approach_m=value)


@pytest.mark.parametrize("value", [-0.5, math.nan])
def test_a_negative_or_nan_approach_gain_is_refused(value: float) -> None:
    with pytest.raises(ValueError, match="open_approach_gain_s"):
        PlannerConfig(open_approach_gain_s=value)
