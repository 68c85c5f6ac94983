"""The prioritised seed staggers robots whose solo paths cross at the same time, and the
cost counts a pair that starts close only if it gets closer."""

from __future__ import annotations

import math

import numpy as np
from planning import scene

from fleet.core.planner import PlannerConfig
from fleet.core.planner.assign import pair_queued
from fleet.core.planner.cost import Limits
from fleet.core.planner.reserve import reservation
from fleet.core.planner.rollout import Rows
from fleet.core.planner.scene import build_fleet


def test_the_seed_makes_one_of_two_crossing_robots_wait() -> None:
    snapshot = scene(
        [(-4.0, 0.0, 0.0), (0.0, -4.0, math.pi / 2)],
        [(4.0, 0.0, 0.0), (0.0, 4.0, math.pi / 2)],
        direction="cw",
    )
    config = PlannerConfig()
    fleet = build_fleet(snapshot, pair_queued(snapshot, config), config)
    seed, paths = reservation(fleet, [0, 1], [], config.reserve_delays_s, 1.0, 0.75)
    assert sorted(seed.delay > 0) == [False, True] and not seed.hold.any()
    gap = np.hypot(*(paths[0] - paths[1]).T)
    assert gap.min() >= 1.0  # the staggered solo paths never come within reach


def test_a_pair_that_starts_close_may_not_get_closer() -> None:
    rows = Rows.standing(np.array([[0.0, 0.0], [0.3, 0.0], [5.0, 0.0]]))
    limits = Limits.of(0.5, rows, np.array([True, False, False]))
    assert limits.allowed[0, 1] < 0.3 and limits.allowed[0, 2] == 0.5
    assert not limits.involved[1, 2]  # two standing robots: nobody's business
    closest = np.array([[np.inf, 0.3, 4.0], [0.3, np.inf, 0.1], [4.0, 0.1, np.inf]])
    assert not limits.broken(closest)
    closest[0, 1] = closest[1, 0] = 0.29
    assert limits.broken(closest)
