"""Scenario builders of ``parkfleet bench fleet`` (the runs themselves need sim agents)."""

from __future__ import annotations

import itertools
import math

from fleet.bench.fleet import (
    case_iii_scenario,
    default_scenarios,
    random_yard_scenario,
    swap_scenario,
)


def test_swap_goals_are_antipodal_and_apart() -> None:
    s = swap_scenario(8)
    for (x, y, _), (gx, gy, _) in zip(s.starts, s.goals, strict=True):
        assert math.isclose(gx, -x, abs_tol=1e-12) and math.isclose(gy, -y, abs_tol=1e-12)
    for a, b in itertools.combinations(s.goals, 2):
        assert math.dist(a[:2], b[:2]) > 1.0  # beyond the peer influence radius


def test_random_yard_is_seeded_inside_and_spaced() -> None:
    a, b = random_yard_scenario(10, 1), random_yard_scenario(10, 1)
    assert a == b and not a.named
    points = [p[:2] for p in a.starts + a.goals]
    assert all(-5 <= x <= 5 and -5 <= y <= 5 for x, y in points)
    assert min(math.dist(p, q) for p, q in itertools.combinations(points, 2)) >= 1.5


def test_case_iii_goal_and_start_lie_outside_the_obstacle_zones() -> None:
    s = case_iii_scenario()
    assert len(s.obstacles) == 2 and s.law_gains is not None
    for o in s.obstacles:
        for p in (s.starts[0], s.goals[0]):
            assert math.hypot(p[0] - o.x, p[1] - o.y) > o.radius


def test_default_scenarios() -> None:
    names = [s.name for s in default_scenarios()]
    assert names == ["swap-2", "swap-4", "swap-8", "swap-16", "yard-s1", "yard-s2", "case-III"]
