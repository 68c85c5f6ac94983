"""The fleet service's one clock: monotonic time for deadlines, wall time for people.

Every deadline of the service (task timeouts, re-sends, event throttling, staleness,
retention, pacing of the planner) is measured on :meth:`Clock.monotonic`, which never
jumps when the system clock is set; :meth:`Clock.wall` [s since the epoch] only stamps
what is stored or displayed (``Task.created_at``/``updated_at``, ``RobotView.last_seen``,
recorded path samples) and decides finished-task retention, which is about stored
timestamps. No other module of ``fleet.service`` reads the time (an import-linter contract).

:class:`SystemClock` is the real one; :class:`FakeClock` is its in-memory twin for tests and
micro-benchmarks (both readings advance together; :meth:`FakeClock.step_wall` moves the wall
clock alone, as an NTP step or an operator would).
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    """What the service reads the time from."""

    def monotonic(self) -> float:
        """Seconds on a clock that never goes back or jumps (deadlines, intervals)."""
        ...

    def wall(self) -> float:
        """Seconds since the epoch (stored timestamps, display)."""
        ...


class SystemClock:
    """:class:`Clock` of the machine: ``time.monotonic`` and ``time.time``."""

    def monotonic(self) -> float:
        return time.monotonic()

    def wall(self) -> float:
        return time.time()


class FakeClock:
    """A :class:`Clock` that moves only when told to (tests, micro-benchmarks)."""

    def __init__(self, monotonic: float = 1000.0, wall: float = 1.7e9) -> None:
        self.t_monotonic = float(monotonic)
        self.t_wall = float(wall)

    def monotonic(self) -> float:
        return self.t_monotonic

    def wall(self) -> float:
        return self.t_wall

    def advance(self, dt: float) -> None:
        """Let ``dt`` seconds pass (both readings)."""
        if dt < 0:
            raise ValueError("time does not go back; use step_wall for a wall-clock step")
        self.t_monotonic += dt
        self.t_wall += dt

    def step_wall(self, dt: float) -> None:
        """Set the wall clock ``dt`` seconds forward (or back): monotonic time stays."""
        self.t_wall += dt
