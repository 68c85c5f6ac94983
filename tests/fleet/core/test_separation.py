"""The smallest-separation tracker agrees with a brute-force minimum over every pair."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from fleet.core.separation import SeparationTracker

coords = st.floats(-20, 20, allow_nan=False)
moves = st.lists(st.tuples(st.sampled_from("abcdef"), coords, coords), max_size=60)


@given(moves)
def test_tracker_matches_brute_force_over_the_positions_seen(
    updates: list[tuple[str, float, float]],
) -> None:
    tracker = SeparationTracker(cutoff=3.0)
    where: dict[str, tuple[float, float]] = {}
    expected = math.inf
    for rid, x, y in updates:
        where[rid] = (x, y)
        for other, (ox, oy) in where.items():
            if other != rid:
                d = math.hypot(x - ox, y - oy)
                if d < 3.0:
                    expected = min(expected, d)
        assert tracker.update(rid, x, y) == expected


def test_removed_robots_no_longer_count_and_bad_positions_are_ignored() -> None:
    tracker = SeparationTracker(cutoff=2.0)
    tracker.update("a", 0.0, 0.0)
    tracker.remove("a")
    assert tracker.update("b", 0.5, 0.0) == math.inf
    assert tracker.update("c", 0.5, 1.0) == 1.0 and tracker.pair == ("b", "c")
    assert tracker.update("c", math.nan, 0.0) == 1.0
