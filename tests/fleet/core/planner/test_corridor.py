"""Corridors: on the predicted path at about the predicted time is inside; elsewhere not."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from fleet.core.planner.corridor import corridor_distance, left_corridor, sample_corridor

SPEED = 1.0  # [m/s] along the x axis
CORRIDOR = sample_corridor(
    np.arange(0.0, 10.5, 0.5), np.c_[np.arange(0.0, 10.5, 0.5), np.zeros(21)], 1
)


@given(st.floats(0.0, 10.0), st.floats(-2.0, 2.0))
def test_distance_is_the_offset_from_the_path_near_that_time(t: float, offset: float) -> None:
    assert math.isclose(
        corridor_distance(CORRIDOR, t, SPEED * t, offset, 0.5), abs(offset), abs_tol=1e-9
    )


@given(st.floats(0.0, 6.0))
def test_a_robot_well_behind_its_prediction_has_left(t: float) -> None:
    late = SPEED * t  # where it should have been 4 s ago
    assert left_corridor(CORRIDOR, t + 4.0, late, 0.0, 0.5, 2.0)
    assert not left_corridor(CORRIDOR, t + 1.0, late, 0.0, 0.5, 2.0)  # a little late: on it


def test_after_the_last_sample_the_robot_should_stand_at_the_end() -> None:
    assert corridor_distance(CORRIDOR, 60.0, 10.0, 0.3, 1.0) == 0.3
    assert left_corridor(CORRIDOR, 60.0, 5.0, 0.0, 0.5, 1.0)


def test_an_empty_corridor_is_never_left() -> None:
    assert not left_corridor((), 1.0, 100.0, 100.0, 0.5, 1.0)


def test_samples_keep_the_last_point() -> None:
    c = sample_corridor(np.arange(5.0), np.c_[np.arange(5.0), np.arange(5.0)], 3)
    assert c == ((0.0, 0.0, 0.0), (3.0, 3.0, 3.0), (4.0, 4.0, 4.0))
