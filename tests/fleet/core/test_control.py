"""Array helpers around the control step: law names, Eq. (2) on recorded controls."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fleet.core import step
from fleet.core.control import body_velocities, is_cw, pose_error, wheel_speeds


def test_law_names_are_validated() -> None:
    assert bool(is_cw("cw")) and not bool(is_cw("ccw"))
    assert is_cw(np.array(["cw", "ccw"])).tolist() == [True, False]
    assert is_cw([True, False]).tolist() == [True, False]
    with pytest.raises(ValueError, match="unknown law"):
        is_cw("left")
    with pytest.raises(ValueError, match="unknown law"):
        is_cw(np.array(["cw", "up"]))


@given(
    arrays(np.float64, 8, elements=st.floats(-30, 30)),
    arrays(np.float64, 8, elements=st.floats(-30, 30)),
    st.floats(0.01, 0.5),
    st.floats(0.05, 1.0),
)
def test_equation_2_on_arrays_is_the_step_conversion_both_ways(
    first: np.ndarray, second: np.ndarray, r: float, b: float
) -> None:
    right, left = wheel_speeds(first, second, r, b)  # (u, omega) -> wheels
    u, omega = body_velocities(first, second, r, b)  # wheels -> (u, omega)
    for i in range(len(first)):
        assert (right[i], left[i]) == step.wheel_speeds(first[i], second[i], r, b)
        assert (u[i], omega[i]) == step.body_velocities(first[i], second[i], r, b)


@given(
    st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-7, 7)),
    st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-7, 7)),
    st.booleans(),
)
def test_pose_error_of_a_posture_sequence_is_the_compiled_one(
    pose: tuple[float, float, float], goal: tuple[float, float, float], cw: bool
) -> None:
    assert pose_error(np.array(pose), list(goal), cw) == step.pose_error(*pose, *goal, cw)
