"""The latency estimator (robot_agent.latency): it finds a simulated drive's command-to-wheel
latency within a few control periods, never below zero, in bounded memory; it falls back to
the configured bound without measurements and reports a latency above it."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fleet.core.params import RobotProfile
from robot_agent.clock import SteppedClock
from robot_agent.latency import LatencyEstimator
from sim_agent.disturbances import Disturbances, DisturbedDrive

DT = 0.02
PROFILE = RobotProfile()


def _drive_and_estimate(
    low: float, high: float, fallback: float, seed: int, ticks: int = 1200
) -> LatencyEstimator:
    """An agent's loop on a drive with latency U(low, high) (in order), 5 % wheel noise and a
    2 % bias (the benchmark's): wheels read, then a new command, every period."""
    clock = SteppedClock()
    disturbances = Disturbances(actuation_noise=0.05, actuation_bias=0.02, latency_s=(low, high))
    rng = np.random.default_rng(seed)
    drive = DisturbedDrive((0.0, 0.0, 0.0), PROFILE, clock, disturbances, rng, max_step=DT)
    estimator = LatencyEstimator(fallback, tolerance=0.2, resolution_s=2 * DT)
    commands = np.random.default_rng(seed + 1)
    right = left = 0.0
    for _ in range(ticks):
        measured_right, measured_left, at = drive.wheel_speeds()
        estimator.measured(at, measured_right, measured_left)
        right = float(np.clip(right + commands.normal(0.0, 3.0), -15.0, 15.0))
        left = float(np.clip(left + commands.normal(0.0, 3.0), -15.0, 15.0))
        drive.command_wheels(right, left)
        estimator.commanded(clock.now(), right, left)
        clock.advance(DT)
    return estimator


@settings(max_examples=25, deadline=None)
@given(
    low=st.floats(0.0, 0.25),
    width=st.floats(0.0, 0.1),
    seed=st.integers(0, 2**20),
)
# Noise made a superseded command look like the one turning: the lower bound of every
# command since rose, a burst of false samples beyond the trim (hi 0.18 s, 0.26 s before).
@example(low=0.0, width=0.0, seed=22)
@example(low=0.08, width=0.0, seed=22)
def test_the_window_holds_the_drive_s_latency_within_a_few_periods(
    low: float, width: float, seed: int
) -> None:
    high = low + width
    window = _drive_and_estimate(low, high, fallback=1.0, seed=seed).window()
    assert window.measured and not window.exceeded
    assert window.lo <= low + DT / 2 and window.hi >= high - DT / 2  # holds it
    # and not much more: the samples resolve a period or two, plus a period of margin, and
    # a few noise matches (2 % wheel bias, 5 % noise: beyond the 1 % trimmed) overstate hi
    assert window.lo >= low - 4 * DT and window.hi <= high + 6 * DT
    assert 0.0 <= window.lo <= window.nominal <= window.hi


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.booleans(),
            st.one_of(st.floats(-1e3, 1e3), st.sampled_from([math.nan, math.inf, -math.inf])),
            st.floats(-30.0, 30.0),
            st.floats(-30.0, 30.0),
        ),
        max_size=400,
    )
)
def test_any_stream_keeps_the_window_at_or_above_zero_in_bounded_memory(
    events: list[tuple[bool, float, float, float]],
) -> None:
    """Commands and measurements in any order, at any (even non-finite or backwards) times."""
    estimator = LatencyEstimator(0.15, min_samples=3, max_samples=10, max_pending=20)
    for is_command, at, right, left in events:
        if is_command and math.isfinite(at):
            estimator.commanded(at, right, left)
        else:
            estimator.measured(at, right, left)
        window = estimator.window()
        assert window.lo >= 0.0 and window.hi >= window.lo
        assert estimator.pending <= 20 and estimator.samples <= 10


def test_without_measurements_the_window_is_the_configured_bound() -> None:
    estimator = LatencyEstimator(0.15)
    for k in range(100):
        estimator.commanded(k * DT, 10.0, -10.0 if k % 2 else 10.0)
    window = estimator.window()
    assert (window.lo, window.hi, window.measured, window.exceeded) == (0.0, 0.15, False, False)


def test_a_latency_above_the_configured_bound_is_reported_and_used() -> None:
    window = _drive_and_estimate(0.25, 0.3, fallback=0.15, seed=7).window()
    assert window.exceeded and window.measured
    assert window.hi >= 0.3 - DT / 2 and window.lo <= 0.25 + DT / 2


def test_a_measured_window_within_the_bound_is_clipped_to_it() -> None:
    """Up to 150 ms as configured: the sampling's period of slack above it is no evidence."""
    window = _drive_and_estimate(0.05, 0.15, fallback=0.15, seed=3).window()
    assert window.measured and not window.exceeded
    assert window.hi == 0.15 and window.lo <= 0.05 + DT / 2
