"""Smooth ego-polar law of Park & Kuipers, as Nav2's graceful controller runs it.

J. J. Park, B. Kuipers, "A smooth control law for graceful motion of differential wheeled
mobile robots in 2D environment", IEEE ICRA 2011, 4896-4902; as implemented by Nav2's
``nav2_graceful_controller`` (``SmoothControlLaw``, ``EgocentricPolarCoordinates``; also
used by ``opennav_docking``):

* ego-polar coordinates of the target: r = ||p_r - p||, phi = theta_r - atan2(dy, dx)
  and delta = theta - atan2(dy, dx), both wrapped to (-pi, pi];
* path curvature kappa = -(1/r) [k_delta (delta - atan(-k_phi phi))
  + (1 + k_phi / (1 + (k_phi phi)^2)) sin(delta)];
* speed v = v_max / (1 + beta |kappa|^lambda), slowed to v_max r / slowdown_radius near
  the target and clamped to [v_min, v_max]; omega = kappa v clamped to +-omega_max with v
  rescaled to keep the curvature;
* Nav2's in-place rotations (forward motion only, its default): while the target lies more
  than ``initial_rotation_tolerance`` (0.75 rad) off the heading the robot turns on the spot
  towards it, and within the position tolerance it turns to the goal heading, each with
  omega = rotation_scaling_factor * omega_max * angle, at least v_angular_min_in_place.

Defaults are Nav2's (k_phi 2, k_delta 1, beta 0.4, lambda 2, v 0.1..0.5 m/s, omega_max
1 rad/s, slowdown radius 1.5 m, rotation factor 0.5, in-place minimum 0.25 rad/s), except
``v_max`` = 1 m/s, the Table 10 robot's top speed (0.05 m x 20 rad/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fleet.core.types import FloatArray
from fleet.paper.baselines.harness import Policy, wrap_to_pi


@dataclass(frozen=True)
class EgoPolar:
    """Park & Kuipers gains and Nav2's speed policy; ``final_radius`` [m] starts the final
    in-place rotation (the harness passes its position tolerance)."""

    k_phi: float = 2.0
    k_delta: float = 1.0
    beta: float = 0.4
    lam: float = 2.0
    v_min: float = 0.1  # [m/s]
    v_max: float = 1.0  # [m/s]
    omega_max: float = 1.0  # [rad/s]
    slowdown_radius: float = 1.5  # [m]
    rotation_factor: float = 0.5
    min_in_place: float = 0.25  # [rad/s]
    initial_rotation: float = 0.75  # [rad]; inf: never turn on the spot first
    final_radius: float = 0.05  # [m]
    name: str = "Park-Kuipers"

    def __post_init__(self) -> None:
        if not (self.k_phi > 0 and self.k_delta > 0 and 0 < self.v_min <= self.v_max):
            raise ValueError("need k_phi, k_delta > 0 and 0 < v_min <= v_max")

    def policy(self, start: FloatArray, goal: FloatArray) -> Policy:
        def control(pose: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
            dx, dy = goal[:, 0] - pose[:, 0], goal[:, 1] - pose[:, 1]
            r = np.hypot(dx, dy)
            sight = np.arctan2(dy, dx)
            phi = wrap_to_pi(goal[:, 2] - sight)
            delta = wrap_to_pi(pose[:, 2] - sight)
            prop = self.k_delta * (delta - np.arctan(-self.k_phi * phi))
            feedback = (1.0 + self.k_phi / (1.0 + (self.k_phi * phi) ** 2)) * np.sin(delta)
            safe_r = np.where(r > 0.0, r, 1.0)
            kappa = -(prop + feedback) / safe_r
            v = self.v_max / (1.0 + self.beta * np.abs(kappa) ** self.lam)
            v = np.minimum(self.v_max * r / self.slowdown_radius, v)
            v = np.clip(v, self.v_min, self.v_max)
            omega = np.clip(kappa * v, -self.omega_max, self.omega_max)
            v = np.where(kappa != 0.0, omega / np.where(kappa != 0.0, kappa, 1.0), v)
            final = r < self.final_radius
            aim = np.abs(delta) > self.initial_rotation
            angle = np.where(final, wrap_to_pi(goal[:, 2] - pose[:, 2]), -delta)
            turn = self.rotation_factor * self.omega_max * angle
            turn = np.where(turn < 0.0, -1.0, 1.0) * np.maximum(np.abs(turn), self.min_in_place)
            in_place = final | aim
            return np.where(in_place, 0.0, v), np.where(in_place, turn, omega)

        return control
