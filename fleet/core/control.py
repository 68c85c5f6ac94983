"""Kinematic Lyapunov posture control laws of Panahandeh et al. (``shared/paper.txt``).

Every function is pure numpy and broadcasts: pass scalars for one robot or arrays of
shape ``(N,)`` for a fleet. Frames: poses ``(x, y, theta)`` are in the world frame
(metres, radians); the posture error is the goal expressed in the robot frame
(x forward, y to the left).

Law names used on every interface:

* ``ccw`` -- Eq. (17), heading error wrapped to [0, 2pi) by (11.a)/(11.b), omega >= 0;
* ``cw``  -- Eq. (20), heading error wrapped to (-2pi, 0] by (11.a)/(21), omega <= 0.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from fleet.core.types import LAWS, BoolArray, FloatArray, Law

TWO_PI = 2.0 * np.pi

#: Default guard of the repulsion singularity at x_OA -> 0, metres (see ``obstacle_repulsion``).
DEFAULT_MIN_X_OA = 0.05


def _f(a: npt.ArrayLike) -> FloatArray:
    return np.asarray(a, dtype=np.float64)


def is_cw(law: Law | npt.ArrayLike) -> BoolArray:
    """Boolean mask of robots using the clockwise law (20); accepts names or booleans."""
    if isinstance(law, str):
        if law not in LAWS:
            raise ValueError(f"unknown law {law!r}; expected 'ccw' or 'cw'")
        return np.asarray(law == "cw")
    arr = np.asarray(law)
    if arr.dtype.kind in "US":
        bad = set(np.unique(arr).tolist()) - set(LAWS)
        if bad:
            raise ValueError(f"unknown law(s) {sorted(bad)}; expected 'ccw' or 'cw'")
        return np.asarray(arr == "cw")
    return arr.astype(bool)


def wrap_to_2pi(theta: npt.ArrayLike) -> FloatArray:
    """Map an orientation to [0, 2pi), Eq. (11.a) generalised to any number of turns."""
    wrapped = np.mod(_f(theta), TWO_PI)
    # np.mod can round a tiny negative angle up to exactly 2pi; keep the interval half-open.
    return np.where(wrapped >= TWO_PI, 0.0, wrapped)


def heading_error(theta_goal: npt.ArrayLike, theta: npt.ArrayLike, cw: npt.ArrayLike) -> FloatArray:
    """Heading error theta_e = theta_r - theta_c of Eq. (5) with the law's wrap.

    Both orientations are first mapped to [0, 2pi) (11.a); the difference then lies in
    (-2pi, 2pi) and is mapped to [0, 2pi) for ``ccw`` (11.b) or to (-2pi, 0] for ``cw`` (21).
    """
    diff = wrap_to_2pi(theta_goal) - wrap_to_2pi(theta)
    ccw_err = np.where(diff < 0.0, diff + TWO_PI, diff)  # (11.b)
    # A difference of -1e-300 plus 2pi rounds to 2pi: that error is really zero.
    ccw_err = np.where(ccw_err >= TWO_PI, 0.0, ccw_err)
    cw_err = ccw_err - TWO_PI  # (21), for ccw_err > 0; it can round to -2pi the same way
    cw_err = np.where(cw_err <= -TWO_PI, 0.0, cw_err)
    return np.where(np.asarray(cw, dtype=bool) & (ccw_err > 0.0), cw_err, ccw_err)


def pose_error(
    pose: npt.ArrayLike, goal: npt.ArrayLike, cw: npt.ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Posture error p_e = (x_e, y_e, theta_e): the goal in the robot frame, Eq. (5).

    Parameters
    ----------
    pose, goal : array_like, shape (..., 3)
        Current and goal postures (x [m], y [m], theta [rad]) in the world frame.
    cw : array_like of bool
        True where the clockwise law (20) is used; selects the heading wrap.
    """
    p, g = _f(pose), _f(goal)
    dx, dy = g[..., 0] - p[..., 0], g[..., 1] - p[..., 1]
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    x_e = c * dx + s * dy
    y_e = -s * dx + c * dy
    return x_e, y_e, heading_error(g[..., 2], p[..., 2], cw)


def ccw_law(
    x_e: npt.ArrayLike, y_e: npt.ArrayLike, theta_e: npt.ArrayLike, gains: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Counter-clockwise law, Eq. (17).

    u = kx x_e, omega = (ky y_e^2 + ktheta theta_e^2) e^(-theta_e).

    ``theta_e`` must be wrapped to [0, 2pi); ``gains`` is (..., 3) = (kx, ky, ktheta) > 0.
    Returns (u [m/s], omega [rad/s]) with omega >= 0.
    """
    k = _f(gains)
    te = _f(theta_e)
    u = k[..., 0] * _f(x_e)
    omega = (k[..., 1] * _f(y_e) ** 2 + k[..., 2] * te**2) * np.exp(-te)
    return u, omega


def cw_law(
    x_e: npt.ArrayLike, y_e: npt.ArrayLike, theta_e: npt.ArrayLike, gains: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Clockwise law, Eq. (20).

    u = kx x_e, omega = -(ky y_e^2 + ktheta theta_e^2) e^(theta_e).

    ``theta_e`` must be wrapped to (-2pi, 0]; returns (u [m/s], omega [rad/s]) with omega <= 0.
    """
    k = _f(gains)
    te = _f(theta_e)
    u = k[..., 0] * _f(x_e)
    omega = -(k[..., 1] * _f(y_e) ** 2 + k[..., 2] * te**2) * np.exp(te)
    return u, omega


def posture_law(
    x_e: npt.ArrayLike,
    y_e: npt.ArrayLike,
    theta_e: npt.ArrayLike,
    gains: npt.ArrayLike,
    cw: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Law (17) where ``cw`` is False and law (20) where it is True, in one pass.

    Both laws share u = kx x_e and |omega| = (ky y_e^2 + ktheta theta_e^2) e^-|theta_e|
    because theta_e >= 0 under (17) and theta_e <= 0 under (20).
    """
    k = _f(gains)
    te = _f(theta_e)
    u = k[..., 0] * _f(x_e)
    magnitude = (k[..., 1] * _f(y_e) ** 2 + k[..., 2] * te**2) * np.exp(-np.abs(te))
    return u, np.where(np.asarray(cw, dtype=bool), -magnitude, magnitude)


def obstacle_repulsion(
    pose: npt.ArrayLike,
    obstacles: npt.ArrayLike,
    influence_radius: npt.ArrayLike,
    k_avoid: float,
    min_x_oa: float = DEFAULT_MIN_X_OA,
) -> FloatArray:
    """Sum of the repulsive terms -K_avoid / x_OA added to u, Eqs. (26)-(27).

    Parameters
    ----------
    pose : array_like, shape (..., 3)
        Robot posture(s) in the world frame.
    obstacles : array_like, shape (M, 2) or (..., M, 2)
        Obstacle centres (x, y) [m] in the world frame (static obstacles or peers).
    influence_radius : array_like, shape (M,) or broadcastable
        Radius [m] of each obstacle's influence zone; only obstacles whose centre lies
        strictly within it contribute.
    k_avoid : float
        K_avoid > 0 [m^2/s].
    min_x_oa : float
        Guard of the singularity at x_OA -> 0: |x_OA| is floored at ``min_x_oa`` [m]
        keeping its sign (x_OA = 0 counts as ahead, so the robot backs off). Each term is
        therefore bounded by K_avoid / min_x_oa; the wheel-speed saturation bounds the sum.

    Returns
    -------
    ndarray, shape (...)
        Velocity correction [m/s] to add to u.
    """
    p, obs = _f(pose), _f(obstacles)
    if obs.size == 0:
        return np.zeros(p.shape[:-1])
    dx = obs[..., 0] - p[..., 0, None]
    dy = obs[..., 1] - p[..., 1, None]
    c, s = np.cos(p[..., 2, None]), np.sin(p[..., 2, None])
    x_oa = c * dx + s * dy  # Eq. (26), first row
    inside = dx * dx + dy * dy < _f(influence_radius) ** 2
    guarded = np.where(x_oa >= 0.0, np.maximum(x_oa, min_x_oa), np.minimum(x_oa, -min_x_oa))
    terms = np.where(inside, -k_avoid / guarded, 0.0)
    return np.asarray(terms.sum(axis=-1), dtype=np.float64)


def wheel_speeds(
    u: npt.ArrayLike, omega: npt.ArrayLike, wheel_radius: npt.ArrayLike, half_axle: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Right and left wheel angular speeds [rad/s] from (u, omega), inverting Eq. (2)."""
    r, b = _f(wheel_radius), _f(half_axle)
    u_, w_ = _f(u), _f(omega)
    return (u_ + b * w_) / r, (u_ - b * w_) / r


def body_velocities(
    right: npt.ArrayLike, left: npt.ArrayLike, wheel_radius: npt.ArrayLike, half_axle: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """(u [m/s], omega [rad/s]) from right/left wheel speeds [rad/s], Eq. (2)."""
    r, b = _f(wheel_radius), _f(half_axle)
    ar, al = _f(right), _f(left)
    return r / 2.0 * (ar + al), r / (2.0 * b) * (ar - al)


def saturate(
    u: npt.ArrayLike,
    omega: npt.ArrayLike,
    wheel_radius: npt.ArrayLike,
    half_axle: npt.ArrayLike,
    max_wheel_speed: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Scale (u, omega) down together so neither wheel exceeds ``max_wheel_speed`` [rad/s].

    Both inputs are divided by the same factor, so the commanded curvature omega/u (and
    hence the path) is kept; only the speed along it drops. ``inf`` disables the limit.
    """
    u_, w_ = _f(u), _f(omega)
    right, left = wheel_speeds(u_, w_, wheel_radius, half_axle)
    peak = np.maximum(np.abs(right), np.abs(left))
    scale = np.where(
        peak > _f(max_wheel_speed), _f(max_wheel_speed) / np.maximum(peak, 1e-300), 1.0
    )
    return u_ * scale, w_ * scale


def lyapunov_v(x_e: npt.ArrayLike, y_e: npt.ArrayLike, theta_e: npt.ArrayLike) -> FloatArray:
    """V = (x_e^2 + y_e^2)/2 + e^theta_e, Eq. (12.a), for the ccw law (theta_e in [0, 2pi))."""
    return 0.5 * (_f(x_e) ** 2 + _f(y_e) ** 2) + np.exp(_f(theta_e))


def lyapunov_p(x_e: npt.ArrayLike, y_e: npt.ArrayLike, theta_e: npt.ArrayLike) -> FloatArray:
    """P = (x_e^2 + y_e^2)/2 + e^-theta_e, Eq. (22), for the cw law (theta_e in (-2pi, 0])."""
    return 0.5 * (_f(x_e) ** 2 + _f(y_e) ** 2) + np.exp(-_f(theta_e))
