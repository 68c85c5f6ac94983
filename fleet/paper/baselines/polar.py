"""Polar-coordinate posture law of Aicardi et al. / Astolfi, as in PythonRobotics.

M. Aicardi, G. Casalino, A. Bicchi, A. Balestrino, "Closed loop steering of unicycle-like
vehicles via Lyapunov techniques", IEEE Robot. Autom. Mag. 2(1), 27-35, 1995 (reference
[10] of the paper); A. Astolfi, "Exponential stabilization of a wheeled mobile robot via
discontinuous control", J. Dyn. Syst. Meas. Control 121(1), 1999; in the form of
PythonRobotics' ``Control/move_to_pose`` (P. Corke, Robotics, Vision & Control, 2017):

* rho = ||p_r - p||, alpha = atan2(dy, dx) - theta, beta = theta_r - theta - alpha, the
  angles wrapped to [-pi, pi);
* u = Kp_rho rho, omega = Kp_alpha alpha + Kp_beta beta; the robot backs up
  (u := -u) when the goal is behind it (|alpha| > pi/2);
* u and omega are clipped separately at the move_to_pose limits (15 m/s, 7 rad/s).

Defaults are move_to_pose's: Kp_rho = 9, Kp_alpha = 15, Kp_beta = -3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fleet.core.types import FloatArray
from fleet.paper.baselines.harness import Policy


def _wrap(angle: FloatArray) -> FloatArray:
    """[-pi, pi), as move_to_pose wraps its angles."""
    return np.asarray((angle + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


@dataclass(frozen=True)
class PolarPose:
    """Gains Kp_rho [1/s] > 0, Kp_alpha [1/s] > Kp_rho, Kp_beta [1/s] < 0; clip limits."""

    kp_rho: float = 9.0
    kp_alpha: float = 15.0
    kp_beta: float = -3.0
    max_speed: float = 15.0  # [m/s]
    max_turn_rate: float = 7.0  # [rad/s]
    name: str = "Astolfi"

    def __post_init__(self) -> None:
        if not (self.kp_rho > 0 and self.kp_alpha > self.kp_rho and self.kp_beta < 0):
            raise ValueError("need Kp_rho > 0, Kp_alpha > Kp_rho and Kp_beta < 0")

    def policy(self, start: FloatArray, goal: FloatArray) -> Policy:
        def control(pose: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
            dx, dy = goal[:, 0] - pose[:, 0], goal[:, 1] - pose[:, 1]
            rho = np.hypot(dx, dy)
            alpha = _wrap(np.arctan2(dy, dx) - pose[:, 2])
            beta = _wrap(goal[:, 2] - pose[:, 2] - alpha)
            u = self.kp_rho * rho
            omega = self.kp_alpha * alpha + self.kp_beta * beta
            u = np.where(np.abs(alpha) > np.pi / 2, -u, u)
            return (
                np.clip(u, -self.max_speed, self.max_speed),
                np.clip(omega, -self.max_turn_rate, self.max_turn_rate),
            )

        return control
