"""Clocks of the control loop and a drift-free periodic scheduler.

Agents judge pose staleness on a :class:`Clock` (monotonic seconds); message stamps use
the wall clock (``time.time()``) instead, as the wire protocol requires.

* :class:`MonotonicClock` -- real time, for a robot computer.
* :class:`SteppedClock` -- simulated time advanced explicitly, one control period per
  tick. A simulation with time scale S paces its ticks every ``period / S`` real seconds
  and advances the clock by ``period``: the control period and the simulated drive's
  integration step are the same clock seconds at any S, so the dynamics are exactly those
  of the batch simulator; if the CPU cannot keep up the simulation just runs slower.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol


class Clock(Protocol):
    """Monotonic time source [s], arbitrary origin."""

    def now(self) -> float: ...


class MonotonicClock:
    """Real time: ``time.monotonic()``."""

    def now(self) -> float:
        return time.monotonic()


class SteppedClock:
    """Simulated time [s] that moves only when :meth:`advance` is called (thread-safe read)."""

    def __init__(self, start: float = 0.0) -> None:
        self._t = float(start)

    def now(self) -> float:
        return self._t

    def advance(self, seconds: float) -> float:
        if seconds < 0:
            raise ValueError("time only moves forward")
        self._t += seconds
        return self._t


def run_periodic(
    period: float,
    stop: threading.Event,
    tick: Callable[[], object],
    max_lag: float | None = None,
) -> tuple[int, int]:
    """Call ``tick()`` every ``period`` real seconds (``time.monotonic``) until ``stop``.

    Deadlines are absolute (no drift): a late tick is followed by earlier ones to catch
    up, unless the loop is more than ``max_lag`` seconds (default one period) behind; then
    the schedule restarts from now instead of bursting. Returns (ticks, overruns).
    """
    lag_limit = period if max_lag is None else max_lag
    ticks = overruns = 0
    deadline = time.monotonic()
    while not stop.is_set():
        tick()
        ticks += 1
        deadline += period
        delay = deadline - time.monotonic()
        if delay < -lag_limit:
            overruns += 1
            deadline = time.monotonic()
            delay = 0.0
        if stop.wait(max(delay, 0.0)):
            break
    return ticks, overruns
