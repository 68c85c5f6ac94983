"""Properties of the pure control laws (Eqs. 2, 5, 11, 17, 20-22, 26-27)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fleet.core.control import (
    TWO_PI,
    body_velocities,
    ccw_law,
    cw_law,
    heading_error,
    is_cw,
    obstacle_repulsion,
    pose_error,
    posture_law,
    saturate,
    wheel_speeds,
    wrap_to_2pi,
)

coord = st.floats(-20, 20, allow_nan=False)
angle = st.floats(-20, 20, allow_nan=False)
gain = st.floats(0.05, 30, allow_nan=False)
posture = st.tuples(coord, coord, angle)
gains_st = st.tuples(gain, gain, gain)


@given(angle)
def test_wrap_to_2pi_lands_in_half_open_interval_and_keeps_the_direction(theta: float) -> None:
    w = float(wrap_to_2pi(theta))
    assert 0.0 <= w < TWO_PI
    assert math.isclose(math.cos(w), math.cos(theta), abs_tol=1e-9)
    assert math.isclose(math.sin(w), math.sin(theta), abs_tol=1e-9)


@given(angle, angle)
def test_heading_error_wraps_per_law(goal: float, theta: float) -> None:
    ccw = float(heading_error(goal, theta, False))
    cw = float(heading_error(goal, theta, True))
    assert 0.0 <= ccw < TWO_PI  # (11.b)
    assert -TWO_PI < cw <= 0.0  # (21)
    # Both describe the same rotation theta_r - theta_c modulo 2pi.
    assert math.isclose(math.cos(ccw), math.cos(goal - theta), abs_tol=1e-9)
    assert math.isclose(math.cos(cw), math.cos(goal - theta), abs_tol=1e-9)
    assert math.isclose(ccw - cw, TWO_PI, abs_tol=1e-9) or abs(ccw - cw) < 1e-9


@given(posture, posture)
def test_pose_error_is_the_goal_in_the_robot_frame(
    pose: tuple[float, ...], goal: tuple[float, ...]
) -> None:
    x_e, y_e, _ = pose_error(pose, goal, False)
    # Rotating (x_e, y_e) back by theta_c and adding the robot position gives the goal (Eq. 5).
    c, s = math.cos(pose[2]), math.sin(pose[2])
    assert math.isclose(pose[0] + c * x_e - s * y_e, goal[0], abs_tol=1e-9)
    assert math.isclose(pose[1] + s * x_e + c * y_e, goal[1], abs_tol=1e-9)


@given(posture, posture, gains_st)
def test_ccw_turns_counter_clockwise_and_cw_clockwise(
    pose: tuple[float, ...], goal: tuple[float, ...], gains: tuple[float, ...]
) -> None:
    x_e, y_e, te = pose_error(pose, goal, False)
    _, omega_ccw = ccw_law(x_e, y_e, te, gains)
    x_e, y_e, te = pose_error(pose, goal, True)
    _, omega_cw = cw_law(x_e, y_e, te, gains)
    assert omega_ccw >= 0.0
    assert omega_cw <= 0.0


@settings(max_examples=50)
@given(
    st.integers(1, 40).flatmap(
        lambda n: st.tuples(
            arrays(np.float64, (n, 3), elements=st.floats(-10, 10)),
            arrays(np.float64, (n, 3), elements=st.floats(-10, 10)),
            arrays(np.float64, (n, 3), elements=st.floats(0.1, 20)),
            arrays(np.bool_, (n,)),
        )
    )
)
def test_vectorised_laws_equal_one_robot_at_a_time(
    data: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    poses, goals, gains, cw = data
    x_e, y_e, te = pose_error(poses, goals, cw)
    u, omega = posture_law(x_e, y_e, te, gains, cw)
    for i in range(len(poses)):
        xi, yi, ti = pose_error(poses[i], goals[i], cw[i])
        law = cw_law if cw[i] else ccw_law
        ui, wi = law(xi, yi, ti, gains[i])
        assert (x_e[i], y_e[i], te[i]) == (xi, yi, ti)
        assert u[i] == pytest.approx(float(ui), rel=1e-12, abs=1e-12)
        assert omega[i] == pytest.approx(float(wi), rel=1e-12, abs=1e-12)


def test_law_names_are_validated() -> None:
    assert bool(is_cw("cw")) and not bool(is_cw("ccw"))
    assert is_cw(np.array(["cw", "ccw"])).tolist() == [True, False]
    with pytest.raises(ValueError, match="unknown law"):
        is_cw("left")


@given(
    st.floats(-5, 5),
    st.floats(-10, 10),
    st.floats(0.01, 0.5),
    st.floats(0.05, 1.0),
    st.floats(0.1, 50),
)
def test_saturation_respects_the_wheel_limit_and_keeps_the_curvature(
    u: float, omega: float, r: float, b: float, limit: float
) -> None:
    us, ws = saturate(u, omega, r, b, limit)
    right, left = wheel_speeds(us, ws, r, b)
    assert max(abs(float(right)), abs(float(left))) <= limit * (1 + 1e-12)
    # Same direction, scaled by one factor in (0, 1]: the path curvature omega/u is kept.
    assert us * u >= 0 and ws * omega >= 0
    assert abs(us) <= abs(u) + 1e-15 and abs(ws) <= abs(omega) + 1e-15
    assert math.isclose(float(us) * omega, float(ws) * u, rel_tol=1e-9, abs_tol=1e-12)
    # Below the limit nothing changes.
    r0, l0 = wheel_speeds(u, omega, r, b)
    if max(abs(float(r0)), abs(float(l0))) <= limit:
        assert (us, ws) == (u, omega)


@given(st.floats(-3, 3), st.floats(-3, 3), st.floats(0.01, 0.5), st.floats(0.05, 1.0))
def test_wheel_speeds_invert_equation_2(u: float, omega: float, r: float, b: float) -> None:
    right, left = wheel_speeds(u, omega, r, b)
    u2, w2 = body_velocities(right, left, r, b)
    assert math.isclose(float(u2), u, abs_tol=1e-9)
    assert math.isclose(float(w2), omega, abs_tol=1e-9)


@given(posture, st.tuples(coord, coord), st.floats(0.1, 3), st.floats(0.1, 10))
def test_repulsion_is_bounded_and_pushes_away_from_the_obstacle(
    pose: tuple[float, ...], obstacle: tuple[float, float], radius: float, k_avoid: float
) -> None:
    min_x = 0.05
    du = float(obstacle_repulsion(pose, [obstacle], [radius], k_avoid, min_x))
    dx, dy = obstacle[0] - pose[0], obstacle[1] - pose[1]
    x_oa = math.cos(pose[2]) * dx + math.sin(pose[2]) * dy  # Eq. (26)
    if math.hypot(dx, dy) >= radius:
        assert du == 0.0  # outside the influence zone the law is unchanged
        return
    assert abs(du) <= k_avoid / min_x + 1e-9  # the guard bounds the singular term
    if x_oa > 0:
        assert du < 0  # obstacle ahead: back off
    elif x_oa < 0:
        assert du > 0  # obstacle behind: move forward
    if abs(x_oa) >= min_x:
        assert math.isclose(du, -k_avoid / x_oa, rel_tol=1e-9)  # Eq. (27) exactly


def test_repulsion_stays_finite_when_the_obstacle_is_exactly_abeam() -> None:
    du = obstacle_repulsion((0.0, 0.0, 0.0), [(0.0, 0.5)], [1.0], 4.0, 0.05)
    assert np.isfinite(du) and abs(float(du)) == pytest.approx(4.0 / 0.05)


def test_repulsion_sums_over_obstacles_for_a_batch_of_robots() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, math.pi]])
    obstacles = np.array([[0.5, 0.0], [-0.5, 0.0], [4.5, 5.0]])
    du = obstacle_repulsion(poses, obstacles, np.ones(3), 2.0)
    # Robot 0: one obstacle ahead and one behind cancel; robot 1 faces -x, obstacle 0.5 ahead.
    assert du[0] == pytest.approx(0.0)
    assert du[1] == pytest.approx(-2.0 / 0.5)
