"""Optimal assignment of unnamed tasks by predicted rollout time (Hungarian method)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from fleet.core.assignment import TaskSpec, optimal_assignment, predicted_times
from fleet.core.params import RobotProfile, Tolerance
from fleet.core.tasks import DEFAULT_GAINS
from fleet.core.types import LAWS
from fleet.core.wire import Obstacle

TOL = Tolerance(position=0.1, heading=0.1)


def _spec(x: float, y: float, theta: float = 0.0) -> TaskSpec:
    return TaskSpec(goal=(x, y, theta), laws=LAWS, gains=dict(DEFAULT_GAINS), tolerance=TOL)


def test_hungarian_beats_first_come_and_is_optimal() -> None:
    cost = np.array([[1.0, 2.0, 9.0], [1.5, 9.0, 9.0], [9.0, 9.0, 1.0]])
    pairs = optimal_assignment(cost)
    total = sum(cost[r, t] for r, t in pairs)
    best = min(
        sum(cost[r, t] for r, t in enumerate(perm)) for perm in itertools.permutations(range(3))
    )
    assert total == best == 4.5
    assert sorted(pairs) == [(0, 1), (1, 0), (2, 2)]


def test_rectangular_and_forbidden_entries() -> None:
    cost = np.array([[np.inf, 1.0], [2.0, np.inf], [0.5, 0.7]])
    pairs = optimal_assignment(cost)
    assert len(pairs) == 2
    assert all(math.isfinite(cost[r, t]) for r, t in pairs)
    assert optimal_assignment(np.zeros((0, 3))) == []


def test_predicted_times_grow_with_distance_and_pick_near_robots() -> None:
    starts = [(0.0, 0.0, 0.0), (6.0, 0.0, 0.0)]
    tasks = [_spec(7.0, 0.0), _spec(1.0, 0.0)]
    cost = predicted_times(starts, tasks, RobotProfile())
    assert cost.shape == (2, 2)
    assert cost[0, 1] < cost[0, 0] and cost[1, 0] < cost[1, 1]
    assert optimal_assignment(cost) == [(1, 0), (0, 1)]


def test_unreachable_goal_costs_more_than_the_horizon() -> None:
    # The goal is inside an obstacle's zone: the robot never arrives.
    cost = predicted_times(
        [(0.0, 0.0, 0.0)], [_spec(3.0, 0.0)], RobotProfile(), [Obstacle(x=3, y=0)], horizon=5.0
    )
    assert cost[0, 0] > 5.0
