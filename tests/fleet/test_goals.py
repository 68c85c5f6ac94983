"""Goal validation: yard, static obstacles' influence zones, other goals and parked robots."""

from __future__ import annotations

import pytest

from fleet.goals import Occupied, validate_goal
from fleet.tasks import GoalRejected
from fleet.wire import Obstacle, Pose

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
