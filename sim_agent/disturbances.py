"""``DisturbedDrive``: a :class:`~sim_agent.drive.SimDrive` with a real robot's imperfections.

Wraps a simulated drive (seeded, reproducible) and adds, between the agent and the robot:

* **pose noise** -- Gaussian noise on the *reported* pose (std ``pose_noise_m`` on x and y
  [m], ``heading_noise_rad`` on theta [rad]); the true pose is untouched;
* **actuation noise** -- each wheel command [rad/s] is multiplied by ``1 + bias + e``, with a
  per-robot, per-wheel constant ``bias ~ N(0, actuation_bias)`` (calibration error) and a
  fresh ``e ~ N(0, actuation_noise)`` per command, then clipped to the wheel limit (a motor
  cannot exceed it);
* **command latency** -- a command (``stop`` included) takes effect ``d ~ U(latency_s)``
  seconds after it is sent, in the order sent (a later command never overtakes an earlier
  one); the robot keeps its previous wheel speeds meanwhile;
* **encoders** -- :meth:`DisturbedDrive.wheel_speeds` reports the wheel speeds actually
  turning (after the latency and the actuation noise), each with Gaussian noise of std
  ``encoder_noise_rad_s`` [rad/s] (0 in :data:`REALISTIC`);
* **link disturbances** (:class:`LinkDisturbances`, :class:`DelayedLink`) -- between robots
  (robot to robot over Wi-Fi): every copy of a peer's state reaches each other robot
  ``d ~ U(delay_s)`` seconds after it was sent, or never (probability ``loss``), each copy
  drawn on its own; copies may overtake each other (a receiver keeps the newest by ``seq``).

The wrapper owns the inner drive's clock: it moves it to each command's effective time,
applies the command there, then to the outer clock's ``now``, so the inner forward-Euler
integration switches commands at the right instants. :data:`REALISTIC` is the set the fleet
benchmark uses (``parkfleet sim --disturbed``), with :data:`REALISTIC_LINK`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from fleet.core.params import RobotProfile
from fleet.core.wire import Pose
from robot_agent.clock import Clock, SteppedClock
from robot_agent.drive import PoseReading, WheelReading
from sim_agent.drive import SimDrive


@dataclass(frozen=True)
class Disturbances:
    """Imperfections of a simulated robot (all zero: a perfect robot).

    ``pose_noise_m`` [m] and ``heading_noise_rad`` [rad]: std of the reported pose's error;
    ``actuation_noise`` and ``actuation_bias``: relative std of each wheel command's error
    (fresh per command) and of a constant per-wheel gain error (per robot);
    ``latency_s``: command latency drawn uniformly in [min, max] [s];
    ``encoder_noise_rad_s`` [rad/s]: std of the measured wheel speeds' error.
    """

    pose_noise_m: float = 0.0
    heading_noise_rad: float = 0.0
    actuation_noise: float = 0.0
    actuation_bias: float = 0.0
    latency_s: tuple[float, float] = (0.0, 0.0)
    encoder_noise_rad_s: float = 0.0

    def __post_init__(self) -> None:
        stds = (self.pose_noise_m, self.heading_noise_rad, self.actuation_noise,
                self.encoder_noise_rad_s)  # fmt: skip
        if not all(math.isfinite(s) and s >= 0 for s in (*stds, self.actuation_bias)):
            raise ValueError("noise standard deviations must be finite and >= 0")
        low, high = self.latency_s
        if not (0 <= low <= high and math.isfinite(high)):
            raise ValueError(f"latency must satisfy 0 <= min <= max, got {self.latency_s}")

    @property
    def active(self) -> bool:
        return any(
            (
                self.pose_noise_m,
                self.heading_noise_rad,
                self.actuation_noise,
                self.actuation_bias,
                self.latency_s[1],
            )
        )


#: What the fleet benchmark runs with: ~1 cm and 0.5 deg of pose noise, 5 % wheel noise
#: per command on top of a 2 % per-robot calibration error, 50-150 ms command latency.
REALISTIC = Disturbances(
    pose_noise_m=0.01,
    heading_noise_rad=math.radians(0.5),
    actuation_noise=0.05,
    actuation_bias=0.02,
    latency_s=(0.05, 0.15),
)


@dataclass(frozen=True)
class LinkDisturbances:
    """Imperfections of the robot-to-robot link (all zero: every state at once, none lost).

    ``delay_s``: delay of each copy of a peer state, uniform in [min, max] [s]; ``loss``:
    probability that a copy never arrives.
    """

    delay_s: tuple[float, float] = (0.0, 0.0)
    loss: float = 0.0

    def __post_init__(self) -> None:
        low, high = self.delay_s
        if not (0 <= low <= high and math.isfinite(high)):
            raise ValueError(f"link delay must satisfy 0 <= min <= max, got {self.delay_s}")
        if not 0.0 <= self.loss < 1.0:
            raise ValueError(f"link loss must be in [0, 1), got {self.loss}")

    @property
    def active(self) -> bool:
        return bool(self.delay_s[1] or self.loss)


#: What ``--disturbed`` adds between robots: 20-200 ms per peer state, 5 % of them lost.
REALISTIC_LINK = LinkDisturbances(delay_s=(0.02, 0.2), loss=0.05)

M = TypeVar("M")


class DelayedLink(Generic[M]):
    """Peer messages among ``robots`` robots through :class:`LinkDisturbances` (seeded).

    :meth:`send` gives every other robot its own copy of a message, due ``d ~ U(delay_s)``
    after ``now`` (or lost); :meth:`deliver` hands out the copies due by ``now``. Delivery
    happens at the ticks of ``period`` (a copy due between ticks arrives at the next one),
    so memory is bounded by robots^2 x (max delay / period + 1) copies.
    """

    def __init__(
        self, robots: int, period: float, link: LinkDisturbances, rng: np.random.Generator
    ) -> None:
        if not period > 0:
            raise ValueError("period must be positive")
        self.robots, self.period, self.link, self.rng = robots, float(period), link, rng
        self._due: dict[int, list[tuple[int, M]]] = {}  # tick -> [(receiver, message)]
        self._next = 0  # first tick not yet delivered
        self.sent = 0
        self.lost = 0

    def _tick(self, t: float) -> int:
        return math.ceil(t / self.period - 1e-9)

    def send(self, sender: int, message: M, now: float) -> None:
        """``sender``'s ``message`` at ``now`` [s], one copy for each other robot."""
        receivers = [r for r in range(self.robots) if r != sender]
        if not receivers:
            return
        low, high = self.link.delay_s
        delays = (
            self.rng.uniform(low, high, len(receivers)) if high > low else [low] * len(receivers)
        )
        kept = self.rng.random(len(receivers)) >= self.link.loss
        self.sent += len(receivers)
        self.lost += int(np.count_nonzero(~kept))
        for receiver, delay, keep in zip(receivers, delays, kept, strict=True):
            if keep:
                due = max(self._tick(now + float(delay)), self._next)
                self._due.setdefault(due, []).append((receiver, message))

    def deliver(self, now: float) -> list[tuple[int, M]]:
        """Every (receiver, message) due by ``now`` [s], in due order."""
        out: list[tuple[int, M]] = []
        last = self._tick(now)
        while self._next <= last:
            out.extend(self._due.pop(self._next, ()))
            self._next += 1
        return out


class DisturbedDrive:
    """A :class:`robot_agent.drive.Drive` adding :class:`Disturbances` to a ``SimDrive``.

    ``clock`` is the agent's clock (the outer time); the inner drive is built here on a
    clock of the wrapper's own. ``rng`` makes every draw reproducible.
    """

    def __init__(
        self,
        start: Pose | tuple[float, float, float],
        profile: RobotProfile,
        clock: Clock,
        disturbances: Disturbances,
        rng: np.random.Generator,
        *,
        max_step: float = 0.02,
    ) -> None:
        self.clock = clock
        self.disturbances = disturbances
        self.profile = profile
        self.rng = rng
        self._inner_clock = SteppedClock(clock.now())
        self.inner = SimDrive(start, profile, self._inner_clock, max_step=max_step)
        bias = disturbances.actuation_bias
        self._gain = (
            (1.0 + float(rng.normal(0.0, bias)), 1.0 + float(rng.normal(0.0, bias)))
            if bias
            else (1.0, 1.0)
        )
        self._pending: deque[tuple[float, float, float]] = deque()  # (due [s], right, left)
        self._last_due = -math.inf

    # -- time ---------------------------------------------------------------------------
    def _move_inner_clock(self, t: float) -> None:
        self._inner_clock.advance(max(0.0, t - self._inner_clock.now()))

    def _catch_up(self) -> None:
        """Apply every command due by now at its due time, then bring the robot to now."""
        now = self.clock.now()
        while self._pending and self._pending[0][0] <= now:
            due, right, left = self._pending.popleft()
            self._move_inner_clock(due)
            self.inner.command_wheels(right, left)
        self._move_inner_clock(now)

    # -- Drive ----------------------------------------------------------------------------
    @property
    def true_pose(self) -> tuple[float, float, float]:
        """Noise-free pose (x [m], y [m], theta [rad]) as of the last call."""
        return self.inner.true_pose

    @property
    def pending_commands(self) -> int:
        """Commands sent but not yet in effect (bounded by max latency / command period)."""
        return len(self._pending)

    def read_pose(self) -> PoseReading:
        self._catch_up()
        pose, stamp = self.inner.read_pose()
        d = self.disturbances
        x, y, theta = pose.as_tuple()
        if d.pose_noise_m:
            x += float(self.rng.normal(0.0, d.pose_noise_m))
            y += float(self.rng.normal(0.0, d.pose_noise_m))
        if d.heading_noise_rad:
            theta += float(self.rng.normal(0.0, d.heading_noise_rad))
        return Pose(x=x, y=y, theta=theta), stamp

    def wheel_speeds(self) -> WheelReading:
        """The wheel speeds [rad/s] turning now (commands due by now applied), with the
        encoders' noise, and now [s] (the optional Drive method)."""
        self._catch_up()
        right, left, now = self.inner.wheel_speeds()
        noise = self.disturbances.encoder_noise_rad_s
        if noise:
            right += float(self.rng.normal(0.0, noise))
            left += float(self.rng.normal(0.0, noise))
        return right, left, now

    def command_wheels(self, right_rad_s: float, left_rad_s: float) -> None:
        """Noisy command, clipped to the wheel limit; a command already beyond the limit (an
        agent's bug) is passed on as sent, for the inner drive to refuse when it applies."""
        limit = self.profile.max_wheel_speed
        noise = self.disturbances.actuation_noise
        wheels = []
        for command, gain in zip((right_rad_s, left_rad_s), self._gain, strict=True):
            error = float(self.rng.normal(0.0, noise)) if noise and command else 0.0
            within = abs(command) <= limit
            wheels.append(min(max(command * (gain + error), -limit), limit) if within else command)
        self._send(wheels[0], wheels[1])

    def stop(self) -> None:
        self._send(0.0, 0.0)

    def _send(self, right: float, left: float) -> None:
        self._catch_up()
        low, high = self.disturbances.latency_s
        if high <= 0.0:
            self.inner.command_wheels(right, left)
            return
        delay = float(self.rng.uniform(low, high)) if high > low else low
        due = max(self.clock.now() + delay, self._last_due)  # in order: never overtakes
        self._last_due = due
        self._pending.append((due, right, left))
