"""Vector-Field-Orientation (VFO) stabilizer of Michałek & Kozłowski.

M. Michałek, K. Kozłowski, "Vector-Field-Orientation feedback control method for a
differentially driven vehicle", IEEE Trans. Control Syst. Technol. 18(1), 45-65, 2010
(reference [23] of the paper), set-point (posture) control. With q = (theta, x, y), the
goal q_t = (theta_t, x_t, y_t) and e* = (x_t - x, y_t - y):

* convergence vector field h* = kp e* + v*, v* = -sigma eta ||e*|| g_t,
  g_t = (cos theta_t, sin theta_t), 0 < eta < kp;
* auxiliary orientation theta_a = Atan2c(sigma h_y, sigma h_x) (atan2 made continuous along
  the run), e_a = theta_a - theta;
* controls u1 = omega = k1 e_a + d(theta_a)/dt and u2 = u = h*^T g(theta), with
  d(theta_a)/dt = (dh_y h_x - h_y dh_x) / ||h*||^2 from dh* = kp de* + dv*,
  de* = -g(theta) u2 and d||e*|| = e*^T de* / ||e*||;
* the decision factor sigma = sgn(e*(0)^T g_t) (+1 forward, -1 backward; +1 when zero);
* at e* = 0 the field is undefined: theta_a := theta_t, d(theta_a)/dt := 0, u2 := 0.

Gains (k1, kp, eta) of the paper's comparative cases: Table 2. The paper gives no sigma;
``sigma`` overrides the rule above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fleet.core.types import FloatArray
from fleet.paper.baselines.harness import Policy, wrap_to_pi


@dataclass(frozen=True)
class VFO:
    """VFO stabilizer with orientation gain ``k1`` [1/s], position gain ``kp`` [1/s] and
    field parameter ``eta`` [1/s] (0 < eta < kp); ``sigma`` None = the initial-error rule."""

    k1: float
    kp: float
    eta: float
    sigma: float | None = None
    name: str = "VFO"

    def __post_init__(self) -> None:
        if not (self.k1 > 0 and self.kp > 0 and self.eta > 0):
            raise ValueError("VFO needs k1, kp, eta > 0")
        if self.sigma is not None and self.sigma not in (-1.0, 1.0):
            raise ValueError("sigma must be +1 or -1")

    def policy(self, start: FloatArray, goal: FloatArray) -> Policy:
        g_t = np.stack([np.cos(goal[:, 2]), np.sin(goal[:, 2])], axis=1)
        if self.sigma is None:
            initial = ((goal[:, :2] - start[:, :2]) * g_t).sum(axis=1)
            sigma = np.where(initial < 0.0, -1.0, 1.0)
        else:
            sigma = np.full(start.shape[0], self.sigma)
        previous: list[FloatArray] = []  # theta_a of the last step (continuity of Atan2c)
        k1, kp, eta = self.k1, self.kp, self.eta

        def control(pose: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
            e = goal[:, :2] - pose[:, :2]
            norm = np.hypot(e[:, 0], e[:, 1])
            g = np.stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])], axis=1)
            h = kp * e - (sigma * eta * norm)[:, None] * g_t
            u2 = (h * g).sum(axis=1)
            de = -g * u2[:, None]
            safe_norm = np.where(norm > 0.0, norm, 1.0)
            dnorm = np.where(norm > 0.0, (e * de).sum(axis=1) / safe_norm, 0.0)
            dh = kp * de - (sigma * eta * dnorm)[:, None] * g_t
            h_sq = (h * h).sum(axis=1)
            defined = (norm > 0.0) & (h_sq > 0.0)
            raw = np.where(defined, np.arctan2(sigma * h[:, 1], sigma * h[:, 0]), goal[:, 2])
            # Atan2c: the branch nearest the last value (the first: nearest the heading).
            reference = previous[0] if previous else pose[:, 2]
            theta_a = reference + wrap_to_pi(raw - reference)
            previous[:] = [theta_a]
            safe_h = np.where(defined, h_sq, 1.0)
            dtheta_a = np.where(defined, (dh[:, 1] * h[:, 0] - h[:, 1] * dh[:, 0]) / safe_h, 0.0)
            omega = k1 * (theta_a - pose[:, 2]) + dtheta_a
            return np.where(norm > 0.0, u2, 0.0), omega

        return control
