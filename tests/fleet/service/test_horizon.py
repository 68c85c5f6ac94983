"""Receding-horizon triggers: corridor deviation at the same robot time, close pairs."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.service.horizon import Corridor, close_pairs


def test_the_prediction_is_interpolated_at_the_robot_time_of_the_state() -> None:
    c = Corridor(0, ((0.0, 0.0, 0.0), (2.0, 2.0, 0.0), (4.0, 2.0, 2.0)), control_hz=50.0)
    assert c.deviation(10, 0.0, 0.0) is None  # no time origin yet
    c.origin_seq = 100.0
    assert c.predicted(-1.0) == (0.0, 0.0)  # before the start: where it starts
    assert c.predicted(1.0) == (1.0, 0.0)
    assert c.predicted(3.0) == (2.0, 1.0)
    assert c.predicted(9.0) == (2.0, 2.0)  # after the end: at its goal
    assert c.deviation(150, 1.0, 0.0) == 0.0  # seq 150 = 1 s of robot time
    assert math.isclose(c.deviation(150, 1.0, 0.3) or 0.0, 0.3)


points = st.lists(
    st.tuples(st.floats(-5, 5, allow_nan=False), st.floats(-5, 5, allow_nan=False), st.booleans()),
    max_size=40,
)


@settings(max_examples=100, deadline=None)
@given(points=points, distance=st.floats(0.05, 3.0))
def test_close_pairs_match_the_brute_force(
    points: list[tuple[float, float, bool]], distance: float
) -> None:
    named = [(f"r{i}", x, y, moving) for i, (x, y, moving) in enumerate(points)]
    expected = {
        (a[0], b[0]) if a[0] < b[0] else (b[0], a[0])
        for i, a in enumerate(named)
        for b in named[i + 1 :]
        if (a[3] or b[3]) and math.hypot(a[1] - b[1], a[2] - b[2]) < distance
    }
    assert close_pairs(named, distance) == expected
