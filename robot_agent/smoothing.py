"""The pose the law decides on: pose readings blended with the wheels' odometry (pure).

A pose reading carries noise (localisation: ~1 cm and 0.5 degree on the benchmark's
robots, fresh every tick). The paper's law and Eq. (27) are stiff near a post or a peer
(tens of m/s per m), so that noise reaches the wheels as a forward speed flipping sign from
tick to tick: cusps (past case III's posts, 250 per trip with that noise alone).
:class:`PoseSmoother` is a fixed-gain complementary filter: it carries its last estimate
to the new reading's instant at the wheels' speeds read with it (the drive's optional
``wheel_speeds``: encoders, ``robot_agent.drive``), in the simulated drive's Euler steps
(:func:`fleet.core.step.integrate_wheels`, at most a control period each), then moves it
``weight`` of the way to the reading. Odometry has no noise of that kind and the readings
keep it from drifting. On exact readings of a drive that switches its wheels when
commanded (no latency), the estimate *is* the reading, bit for bit: perfect robots, and
the planner's model of them, are unchanged.

It feeds the **nominal command only** (``SafetyConfig.reading_weight``; the agent,
:mod:`robot_agent.agent`): the stop rule and the safety filter keep the measured pose and
its spread, so what the filter guarantees, and assumes, is the same with it on or off
(docs/safety.md, "Latency compensation and pose smoothing").

Frames and units: world frame, metres, radians, seconds on the agent's clock.
"""

from __future__ import annotations

import math

from fleet.core.params import RobotProfile
from fleet.core.step import integrate_wheels

Posture = tuple[float, float, float]
#: (right, left [rad/s], measured at [s]): the drive's ``wheel_speeds()`` reading.
Wheels = tuple[float, float, float]

#: A reading this many times ``pose_error_m`` (``heading_error_rad``) from the carried
#: estimate is a jump (a relocalisation, a robot moved by hand), not noise: the estimate
#: restarts from it.
JUMP_ERRORS = 10.0


class PoseSmoother:
    """Own pose readings blended with odometry (module docstring).

    ``weight`` in (0, 1]: the share of each new reading (1: the reading alone, off);
    ``profile``: wheel radius and half axle of Eq. (2); ``period`` [s]: the longest Euler
    step (the control period); ``jump_m`` [m], ``jump_rad`` [rad]: a reading farther than
    that from the carried estimate restarts it; so does a gap of more than ``max_gap_s``
    [s] between readings, or a reading without wheel speeds.
    """

    def __init__(
        self,
        weight: float,
        profile: RobotProfile,
        period: float,
        *,
        jump_m: float,
        jump_rad: float,
        max_gap_s: float,
    ) -> None:
        if not 0.0 < weight <= 1.0:
            raise ValueError(f"reading weight must be in (0, 1], got {weight}")
        if not (period > 0.0 and jump_m > 0.0 and jump_rad > 0.0 and max_gap_s > 0.0):
            raise ValueError("period, jump bounds and gap must be positive")
        self.weight = float(weight)
        self.profile = profile
        self.period = float(period)
        self.jump_m, self.jump_rad, self.max_gap_s = float(jump_m), float(jump_rad), max_gap_s
        self._estimate: Posture | None = None
        self._stamp = -math.inf  # [s] of the estimate
        self.restarts = 0  # restarts after a jump or a gap

    @property
    def estimate(self) -> Posture | None:
        """The current estimate (None before the first reading)."""
        return self._estimate

    def update(self, pose: Posture, stamp: float, wheels: Wheels | None) -> Posture:
        """The estimate after the reading ``pose`` measured at ``stamp`` [s], with the
        wheels' speeds ``wheels`` read at the same tick (None: the drive has none)."""
        estimate = self._estimate
        gap = stamp - self._stamp
        if estimate is not None and gap == 0.0:
            return estimate  # the same reading again: nothing new
        if self.weight >= 1.0 or wheels is None or estimate is None:
            return self._restart(pose, stamp, counted=False)  # off, no odometry, or a start
        if not 0.0 < gap <= self.max_gap_s:
            return self._restart(pose, stamp, counted=True)
        # Carry the estimate to the reading's instant at the wheels' speeds read with it
        # (what turned since the last reading, exactly so when no command switched between).
        right, left = wheels[0], wheels[1]
        steps = max(1, math.ceil(gap / self.period - 1e-9))
        x, y, theta = integrate_wheels(
            estimate[0], estimate[1], estimate[2], right, left,
            self.profile.wheel_radius, self.profile.half_axle, gap / steps, steps,
        )  # fmt: skip
        dx, dy = pose[0] - x, pose[1] - y
        dtheta = math.remainder(pose[2] - theta, 2.0 * math.pi)
        if math.hypot(dx, dy) > self.jump_m or abs(dtheta) > self.jump_rad:
            return self._restart(pose, stamp, counted=True)
        w = self.weight
        # The heading as the reading's plus a share of the way back to the carried one, so
        # the estimate keeps the reading's wrap.
        self._estimate = (x + w * dx, y + w * dy, pose[2] - (1.0 - w) * dtheta)
        self._stamp = stamp
        return self._estimate

    def _restart(self, pose: Posture, stamp: float, *, counted: bool) -> Posture:
        self.restarts += counted
        self._estimate = (float(pose[0]), float(pose[1]), float(pose[2]))
        self._stamp = stamp
        return self._estimate
