"""Goal validation: yard, static obstacles' influence zones, other goals and parked robots."""

from __future__ import annotations

import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fleet.core.goals import GoalIndex, Occupied, validate_goal
from fleet.core.tasks import GoalRejected
from fleet.core.wire import Obstacle, Pose

YARD = (-10.0, 10.0, -10.0, 10.0)


def test_a_free_goal_is_accepted() -> None:
    validate_goal(Pose(x=0, y=0), YARD, [Obstacle(x=3, y=0)], [Occupied(0, 2, "x")], 1.0)


@pytest.mark.parametrize("x,y", [(10.5, 0), (0, -10.01), (-11, 11)])
def test_outside_the_yard_is_rejected(x: float, y: float) -> None:
    with pytest.raises(GoalRejected, match="outside the yard"):
        validate_goal(Pose(x=x, y=y), YARD, [], [], 1.0)


def test_inside_an_obstacle_zone_is_rejected_naming_it() -> None:
    with pytest.raises(GoalRejected, match=r"influence zone of obstacle 1 at \(2.00, 2.00\)"):
        validate_goal(
            Pose(x=2.5, y=2), YARD, [Obstacle(x=-5, y=0), Obstacle(x=2, y=2, radius=1)], [], 1.0
        )


def test_edge_of_an_obstacle_zone_is_rejected() -> None:
    with pytest.raises(GoalRejected):
        validate_goal(Pose(x=1, y=0), YARD, [Obstacle(x=0, y=0, radius=1)], [], 1.0)


def test_too_near_another_goal_or_parked_robot_is_rejected_naming_it() -> None:
    occupied = [Occupied(5, 5, "the goal of task abc"), Occupied(-3, 0, "arrived robot r2")]
    with pytest.raises(GoalRejected, match="the goal of task abc"):
        validate_goal(Pose(x=5.5, y=5), YARD, [], occupied, 1.0)
    with pytest.raises(GoalRejected, match="arrived robot r2"):
        validate_goal(Pose(x=-3, y=0.9), YARD, [], occupied, 1.0)
    validate_goal(Pose(x=-3, y=1.1), YARD, [], occupied, 1.0)


coord = st.floats(min_value=-20, max_value=20, allow_nan=False)


@example(
    points=[(0.0, 0.0), (0.0, -1.175494351e-38)],
    removed=[],
    queries=[(0.0, 0.25)],
    radius=0.25,
    cell=1.0,
)  # a point one cell down, at a distance that rounds to r
@settings(max_examples=200)
@given(
    st.lists(st.tuples(coord, coord), max_size=40),
    st.lists(st.integers(min_value=0, max_value=39), max_size=20),
    st.lists(st.tuples(coord, coord), min_size=1, max_size=10),
    st.floats(min_value=0.05, max_value=3.0),
    st.floats(min_value=0.1, max_value=2.0),
)
def test_goal_index_finds_what_the_brute_force_check_finds(
    points: list[tuple[float, float]],
    removed: list[int],
    queries: list[tuple[float, float]],
    radius: float,
    cell: float,
) -> None:
    """The incremental grid agrees with checking every point (after adds and removes)."""
    index = GoalIndex(cell)
    live: dict[str, Occupied] = {}
    for k, (x, y) in enumerate(points):
        index.add(f"t{k}", Occupied(x, y, f"t{k}"))
        live[f"t{k}"] = Occupied(x, y, f"t{k}")
    for k in removed:
        index.remove(f"t{k}")
        live.pop(f"t{k}", None)
    assert len(index) == len(live)
    for qx, qy in queries:
        brute = {p.what for p in live.values() if math.hypot(qx - p.x, qy - p.y) <= radius}
        found = list(index.near(qx, qy, radius))
        assert {p.what for p in found} == brute
        dists = [math.hypot(qx - p.x, qy - p.y) for p in found]
        assert dists == sorted(dists)  # nearest first
        goal = Pose(x=qx, y=qy)
        try:
            validate_goal(goal, (-20, 20, -20, 20), [], live.values(), radius)
            rejected_brute = False
        except GoalRejected:
            rejected_brute = True
        try:
            validate_goal(goal, (-20, 20, -20, 20), [], index.near(qx, qy, radius), radius)
            rejected_index = False
        except GoalRejected:
            rejected_index = True
        assert rejected_index == rejected_brute


def test_goal_index_moves_a_key_and_rejects_bad_input() -> None:
    index = GoalIndex(1.0)
    index.add("a", Occupied(0.0, 0.0, "a"))
    index.add("a", Occupied(5.0, 5.0, "a"))
    assert len(index) == 1 and "a" in index
    assert list(index.near(0.0, 0.0, 1.0)) == []
    assert [p.what for p in index.near(5.2, 5.0, 1.0)] == ["a"]
    index.remove("a")
    index.remove("a")  # absent: nothing
    assert len(index) == 0
    with pytest.raises(ValueError):
        GoalIndex(0.0)
    with pytest.raises(ValueError):
        index.add("b", Occupied(math.inf, 0.0, "b"))


def test_a_goal_whose_parked_body_would_touch_an_obstacle_body_is_rejected() -> None:
    """Outside the influence zone but within robot radius + contact margin of the body."""
    post = [Obstacle(x=0.0, y=0.0, radius=0.3, body=0.3)]
    with pytest.raises(GoalRejected, match=r"within 0\.05 m of its body"):
        validate_goal(Pose(x=0.5, y=0.0), YARD, post, [], 1.0, margin=0.2, contact_margin=0.05)
    validate_goal(Pose(x=0.56, y=0.0), YARD, post, [], 1.0, margin=0.2, contact_margin=0.05)
