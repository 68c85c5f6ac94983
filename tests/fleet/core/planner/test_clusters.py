"""Encounters and clusters: both moving -> one cluster; one standing -> a phantom."""

from __future__ import annotations

import numpy as np

from fleet.core.planner.clusters import Cluster, clusters, components, encounters

T = 20  # samples


def line(x0: float, y0: float, x1: float, y1: float, start: int = 0, stop: int = T) -> np.ndarray:
    """A path standing at (x0, y0) until ``start``, moving to (x1, y1) by ``stop``."""
    s = np.clip((np.arange(T) - start) / max(stop - start, 1), 0.0, 1.0)
    return np.stack([x0 + s * (x1 - x0), y0 + s * (y1 - y0)], axis=1)


def moving_mask(start: int = 0, stop: int = T) -> np.ndarray:
    t = np.arange(T)
    return (t >= start) & (t < stop)


def test_robots_that_meet_while_both_move_are_one_cluster() -> None:
    paths = np.stack([line(-5, 0, 5, 0), line(0, -5, 0, 5), line(20, 0, 30, 0)])
    moving = np.stack([moving_mask()] * 3)
    found = clusters(paths, moving, 3, np.zeros((0, 2)), reach=1.0, window=1)
    assert [c.movers for c in found] == [(0, 1), (2,)]
    assert all(c.phantoms == () for c in found)


def test_robots_that_pass_the_same_place_at_other_times_are_apart() -> None:
    paths = np.stack([line(-5, 0, 5, 0, 0, 5), line(0, -5, 0, 5, 12, 17)])
    moving = np.stack([moving_mask(0, 5), moving_mask(12, 17)])
    assert components(2, encounters(paths, moving, [0, 1], 1.0, 1).pairs) == [[0], [1]]


def test_a_robot_passing_another_where_it_waits_gets_a_phantom() -> None:
    # robot 1 waits at (0, 0.5) until sample 15 while robot 0 passes along the x axis
    paths = np.stack([line(-5, 0, 5, 0, 0, 10), line(0, 0.5, 0, 5, 15, 19)])
    moving = np.stack([moving_mask(0, 10), moving_mask(15, 19)])
    found = clusters(paths, moving, 2, np.zeros((0, 2)), reach=1.0, window=1)
    assert [c.movers for c in found] == [(0,), (1,)]
    assert found[0].phantoms == ((0.0, 0.5, 1),)
    assert found[0].knows((0.01, 0.5, 1)) and not found[0].knows((0.0, 0.5, 0))
    assert found[1].phantoms == ()


def test_a_robot_passing_one_parked_at_its_goal_gets_a_phantom_there() -> None:
    paths = np.stack([line(-5, 0, 5, 0, 10, 19), line(0, 5, 0, 0.5, 0, 5)])
    moving = np.stack([moving_mask(10, 19), moving_mask(0, 5)])
    found = clusters(paths, moving, 2, np.zeros((0, 2)), reach=1.0, window=1)
    assert found[0] == Cluster((0,), (), ((0.0, 0.5, 1),))


def test_standing_robots_join_the_clusters_that_pass_near_them() -> None:
    paths = np.stack([line(-5, 0, 5, 0), line(-5, 10, 5, 10)])
    standing = np.array([[0.0, 0.5], [0.0, 9.5], [40.0, 40.0]])
    found = clusters(paths, np.ones((2, T), dtype=bool), 2, standing, reach=1.0, window=1)
    assert [(c.movers, c.standing) for c in found] == [((0,), (0,)), ((1,), (1,))]
