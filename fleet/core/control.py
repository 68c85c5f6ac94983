"""Law names and array helpers around the control step of Panahandeh et al. (``shared/paper.txt``).

The control step itself -- posture error (5) with the wraps (11)/(21), laws (17)/(20),
repulsion (27), saturation, the safety filter, Euler -- exists once, compiled, in
:mod:`fleet.core.step`. This module keeps what works on whole arrays around it: law names,
Eq. (2) both ways (recorded controls, drives that take body velocities), the Lyapunov
functions (12.a)/(22) for analysis, and :func:`pose_error` on posture sequences.

Law names used on every interface:

* ``ccw`` -- Eq. (17), heading error wrapped to [0, 2pi) by (11.a)/(11.b), omega >= 0;
* ``cw``  -- Eq. (20), heading error wrapped to (-2pi, 0] by (11.a)/(21), omega <= 0.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from fleet.core import step
from fleet.core.types import LAWS, BoolArray, FloatArray, Law

#: Default guard of the repulsion singularity at x_OA -> 0, metres (``fleet.core.step``).
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


def wheel_speeds(
    u: npt.ArrayLike, omega: npt.ArrayLike, wheel_radius: npt.ArrayLike, half_axle: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Right and left wheel angular speeds [rad/s] of recorded (u, omega), inverting Eq. (2)."""
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


def pose_error(
    pose: npt.ArrayLike, goal: npt.ArrayLike, cw: bool | np.bool_
) -> tuple[float, float, float]:
    """Posture error (x_e [m], y_e [m], theta_e [rad]) of one robot, Eq. (5) with the law's
    wrap: :func:`fleet.core.step.pose_error` on (x, y, theta) sequences (world frame)."""
    p, g = _f(pose), _f(goal)
    return step.pose_error(
        float(p[0]), float(p[1]), float(p[2]), float(g[0]), float(g[1]), float(g[2]), bool(cw)
    )


def lyapunov_v(x_e: npt.ArrayLike, y_e: npt.ArrayLike, theta_e: npt.ArrayLike) -> FloatArray:
    """V = (x_e^2 + y_e^2)/2 + e^theta_e, Eq. (12.a), for the ccw law (theta_e in [0, 2pi))."""
    return 0.5 * (_f(x_e) ** 2 + _f(y_e) ** 2) + np.exp(_f(theta_e))


def lyapunov_p(x_e: npt.ArrayLike, y_e: npt.ArrayLike, theta_e: npt.ArrayLike) -> FloatArray:
    """P = (x_e^2 + y_e^2)/2 + e^-theta_e, Eq. (22), for the cw law (theta_e in (-2pi, 0])."""
    return 0.5 * (_f(x_e) ** 2 + _f(y_e) ** 2) + np.exp(-_f(theta_e))
