"""Array helpers around the control step: law names, Eq. (2) on recorded controls."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fleet.core import step
from fleet.core.control import is_cw, wheel_speeds


def test_law_names_are_validated() -> None:
    assert bool(is_cw("cw")) and not bool(is_cw("ccw"))
    assert is_cw(np.array(["cw", "ccw"])).tolist() == [True, False]
    assert is_cw([True, False]).tolist() == [True, False]
    with pytest.raises(ValueError, match="unknown law"):
        is_cw("left")
    with pytest.raises(ValueError, match="unknown law"):
        is_cw(np.array(["cw", "up"]))


@given(
    arrays(np.float64, 8, elements=st.floats(-3, 3)),
    arrays(np.float64, 8, elements=st.floats(-3, 3)),
    st.floats(0.01, 0.5),
    st.floats(0.05, 1.0),
)
def test_wheel_speeds_of_recorded_controls_are_the_step_conversion(
    u: np.ndarray, omega: np.ndarray, r: float, b: float
) -> None:
    right, left = wheel_speeds(u, omega, r, b)
    for i in range(len(u)):
        assert (right[i], left[i]) == step.wheel_speeds(u[i], omega[i], r, b)
