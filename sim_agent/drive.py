"""``SimDrive``: a kinematic unicycle standing in for a robot (same model as the core).

The wheel command is held between calls (zero-order hold) and the pose is integrated by
forward Euler on Eq. (3) -- x' = u cos(theta), y' = u sin(theta), theta' = omega, with
(u, omega) from the wheel speeds by Eq. (2) -- by the compiled control step's own Euler
update (:func:`fleet.core.step.integrate_wheels`), as in ``fleet.core.simulate``. Integration
is lazy: every call advances the true pose to ``clock.now()`` in steps of at most
``max_step`` clock seconds. On a :class:`~robot_agent.clock.SteppedClock` advanced by one
control period per tick (``sim_agent.fleet``), that is one Euler step of the control
period per tick, whatever the time scale; on a real clock it follows real time.

Optional Gaussian noise (std of x, y [m] and theta [rad]) is added to the *reported* pose
only; the true pose is kept in :attr:`true_pose`.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from fleet.core.params import RobotProfile
from fleet.core.step import integrate_wheels
from fleet.core.wire import Pose
from fleet.io.settings import RobotSettings
from robot_agent.clock import Clock, MonotonicClock
from robot_agent.drive import PoseReading, WheelReading

#: Cap on the Euler steps of one catch-up (a stalled process moves the robot in bigger steps).
MAX_SUBSTEPS = 200


class SimDrive:
    """Simulated differential-drive robot implementing :class:`robot_agent.drive.Drive`."""

    def __init__(
        self,
        start: Pose | tuple[float, float, float],
        profile: RobotProfile,
        clock: Clock | None = None,
        *,
        max_step: float = 0.02,
        noise_std: tuple[float, float, float] = (0.0, 0.0, 0.0),
        rng: np.random.Generator | None = None,
    ) -> None:
        if not max_step > 0:
            raise ValueError("max_step must be positive")
        pose = start.as_tuple() if isinstance(start, Pose) else tuple(map(float, start))
        self.x, self.y, self.theta = pose
        self.profile = profile
        self.clock: Clock = clock or MonotonicClock()
        self.max_step = float(max_step)
        self.noise_std = tuple(float(s) for s in noise_std)
        self.rng = rng or np.random.default_rng()
        self.right = 0.0
        self.left = 0.0
        self._t = self.clock.now()
        self._lock = threading.Lock()  # tests read true_pose from other threads

    def _advance(self) -> float:
        now = self.clock.now()
        elapsed = now - self._t
        self._t = now
        if elapsed <= 0.0 or (self.right == 0.0 and self.left == 0.0):
            return now
        # At least one step: a hair of time (a latency's due instant a rounding error past a
        # tick) is integrated, not divided by zero steps.
        steps = max(1, min(math.ceil(elapsed / self.max_step - 1e-9), MAX_SUBSTEPS))
        self.x, self.y, self.theta = integrate_wheels(
            self.x, self.y, self.theta, self.right, self.left,
            self.profile.wheel_radius, self.profile.half_axle, elapsed / steps, steps,
        )  # fmt: skip
        return now

    @property
    def true_pose(self) -> tuple[float, float, float]:
        """Noise-free pose (x [m], y [m], theta [rad]) as of the last call."""
        with self._lock:
            return (self.x, self.y, self.theta)

    def read_pose(self) -> PoseReading:
        with self._lock:
            now = self._advance()
            x, y, theta = self.x, self.y, self.theta
        sx, sy, st = self.noise_std
        if sx or sy or st:
            x += float(self.rng.normal(0.0, sx)) if sx else 0.0
            y += float(self.rng.normal(0.0, sy)) if sy else 0.0
            theta += float(self.rng.normal(0.0, st)) if st else 0.0
        return Pose(x=x, y=y, theta=theta), now

    def wheel_speeds(self) -> WheelReading:
        """The wheel speeds [rad/s] turning now, and now [s] (the optional Drive method)."""
        with self._lock:
            now = self._advance()
            return self.right, self.left, now

    def command_wheels(self, right_rad_s: float, left_rad_s: float) -> None:
        limit = self.profile.max_wheel_speed
        if not (abs(right_rad_s) <= limit * (1 + 1e-9) and abs(left_rad_s) <= limit * (1 + 1e-9)):
            raise ValueError(
                f"wheel command ({right_rad_s:.3f}, {left_rad_s:.3f}) rad/s exceeds the "
                f"limit {limit} rad/s"
            )
        with self._lock:
            self._advance()
            self.right, self.left = float(right_rad_s), float(left_rad_s)

    def stop(self) -> None:
        with self._lock:
            self._advance()
            self.right = self.left = 0.0


def make_drive(settings: RobotSettings) -> SimDrive:
    """Drive factory of ``parkfleet agent --drive sim``: a simulated unicycle starting at
    ``settings.sim_start`` with the robot's profile, stepped at the control period."""
    return SimDrive(settings.sim_start, settings.profile, max_step=1.0 / settings.control_rate_hz)
