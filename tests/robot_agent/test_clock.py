"""Clocks of the control loop and the periodic scheduler."""

from __future__ import annotations

import threading

import pytest

from robot_agent.clock import MonotonicClock, SteppedClock, run_periodic


def test_stepped_clock_moves_only_when_advanced_and_never_back() -> None:
    clock = SteppedClock(start=5.0)
    assert clock.now() == 5.0 == clock.now()
    assert clock.advance(0.02) == pytest.approx(5.02)
    assert clock.now() == pytest.approx(5.02)
    with pytest.raises(ValueError, match="forward"):
        clock.advance(-1e-9)


def test_monotonic_clock_never_goes_back() -> None:
    clock = MonotonicClock()
    readings = [clock.now() for _ in range(1000)]
    assert readings == sorted(readings)


def test_run_periodic_ticks_until_stopped_and_reports_the_count() -> None:
    stop = threading.Event()
    seen: list[int] = []

    def tick() -> None:
        seen.append(len(seen))
        if len(seen) == 5:
            stop.set()

    ticks, overruns = run_periodic(0.001, stop, tick)
    assert ticks == 5 and seen == [0, 1, 2, 3, 4]
    assert 0 <= overruns <= ticks


def test_run_periodic_restarts_its_schedule_after_a_long_stall() -> None:
    """A tick that overruns by more than ``max_lag`` counts as an overrun (and the loop
    goes on from now instead of bursting to catch up)."""
    stop = threading.Event()
    stalled = threading.Event()
    count = 0

    def tick() -> None:
        nonlocal count
        count += 1
        if count == 1:
            stalled.wait(0.05)  # one slow tick: 50 ms against a 1 ms period
        if count == 3:
            stop.set()

    ticks, overruns = run_periodic(0.001, stop, tick, max_lag=0.01)
    assert ticks == 3 and overruns >= 1
