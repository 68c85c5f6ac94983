"""Two-phase finite-time (FT) posture controller after Thomas, Bandyopadhyay & Vachhani.

M. Thomas, B. Bandyopadhyay, L. Vachhani, "Posture stabilization of unicycle mobile robot
using finite time control techniques", IFAC-PapersOnLine 49(1), 379-384, 2016 (reference
[21] of the paper). **Reconstruction**: [21] itself is not available here, so this module
implements what the paper says of it -- a chained-form controller whose orientation
singularity is at 90 degrees, in two phases switched at time T with a jump of the linear
velocity, one of the errors vanishing in the first phase and the other in the second
(Sections 1 and 4) -- with the textbook finite-time ingredients its seven gains (Table 3:
K1, K2, k1, k2, alpha1, alpha2, T) name:

* chained form in the goal frame: x1 = x_bar, x2 = tan(theta_bar), x3 = y_bar, so
  dx1/dt = u1, dx2/dt = u2, dx3/dt = x2 u1 with u = u1 / cos(theta_bar) and
  omega = u2 cos^2(theta_bar) (singular at theta_bar = +-pi/2);
* phase 1 (t < T): u1 = K1 d, d = sgn(x1(0)) (+1 at 0): the robot drives along the goal
  axis at constant rate while (x2, x3) are steered to zero;
* phase 2 (t >= T): u1 = -K2 sig(x1)^alpha2 (finite-time convergence of x1; the jump of
  u1 at T is the discontinuity the paper criticises);
* both phases: (x3, x2) form a double integrator in the travelled x1-distance s
  (dx3/ds = z2, dz2/ds = u2/u1 with z2 = sgn(u1) x2); the Bhat-Bernstein finite-time
  law dz2/ds = -k1 sig(z2)^alpha1 - k2 sig(x3)^alpha2 (Bhat & Bernstein, IEEE TAC 43(5),
  1998) gives u2 = u1 (-k1 sig(z2)^alpha1 - k2 sig(x3)^alpha2), defined in both
  directions of travel and zero when u1 is.

sig(z)^a = sign(z) |z|^a. How far this matches the paper's FT rows (Tables 5, 7, 9), and
what the paper leaves unspecified, is in the docs/paper.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from fleet.core.types import FloatArray
from fleet.paper.baselines.harness import Policy, wrap_to_pi

#: Floor of |cos(theta_bar)| at the chained form's singularity (theta_bar = +-90 degrees).
MIN_COS = 1e-6


def sig(z: npt.ArrayLike, a: float) -> FloatArray:
    """sign(z) |z|^a."""
    arr = np.asarray(z, dtype=np.float64)
    return np.asarray(np.sign(arr) * np.abs(arr) ** a, dtype=np.float64)


@dataclass(frozen=True)
class FiniteTime:
    """Table 3's gains: K1 [m/s], K2, k1, k2 > 0, exponents alpha1, alpha2 > 0, switch T [s]."""

    K1: float
    K2: float
    k1: float
    k2: float
    alpha1: float
    alpha2: float
    T: float
    name: str = "FT"

    def __post_init__(self) -> None:
        values = (self.K1, self.K2, self.k1, self.k2, self.alpha1, self.alpha2, self.T)
        if not all(v > 0 for v in values):
            raise ValueError("FT gains, exponents and T must be positive")

    def policy(self, start: FloatArray, goal: FloatArray) -> Policy:
        c_t, s_t = np.cos(goal[:, 2]), np.sin(goal[:, 2])

        def chained(pose: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
            dx, dy = pose[:, 0] - goal[:, 0], pose[:, 1] - goal[:, 1]
            theta_bar = wrap_to_pi(pose[:, 2] - goal[:, 2])
            cos_bar = np.cos(theta_bar)
            cos_bar = np.where(cos_bar >= 0.0, 1.0, -1.0) * np.maximum(np.abs(cos_bar), MIN_COS)
            x2 = np.sin(theta_bar) / cos_bar
            return c_t * dx + s_t * dy, x2, c_t * dy - s_t * dx, cos_bar

        direction = np.where(chained(start)[0] < 0.0, -1.0, 1.0)

        def control(pose: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
            x1, x2, x3, cos_bar = chained(pose)
            # Phase 1 drives along the goal axis; phase 2 brings x1 to zero in finite time.
            u1 = self.K1 * direction if t < self.T else -self.K2 * sig(x1, self.alpha2)
            z2 = np.where(u1 < 0.0, -x2, x2)
            u2 = u1 * (-self.k1 * sig(z2, self.alpha1) - self.k2 * sig(x3, self.alpha2))
            return u1 / cos_bar, u2 * cos_bar**2

        return control
