"""``parkfleet bench estop`` runs end to end and reports consistent rows (no timing asserts)."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from fleet.bench.estop import wheels_stopped
from fleet.io.processes import parkfleet_command


@pytest.mark.integration
def test_bench_estop_measures_every_robot_of_every_trial() -> None:
    done = subprocess.run(
        parkfleet_command("bench", "estop", "--robots", "2", "--trials", "3", "--json"),
        capture_output=True,
        text=True,
        timeout=300,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    (row,) = json.loads(done.stdout.splitlines()[-1])["rows"]
    assert row["robots"] == 2 and row["samples"] == 6
    assert row["estop_states_with_speed"] == 0 and row["dropped"] == 0
    assert row["tick_p50_ms"] <= row["tick_max_ms"]
    assert row["received_p50_ms"] <= row["received_max_ms"]
    # disturbed drives by default: the wheels stop after the zeroing tick, within the bound
    assert row["disturbed"] and row["tick_p50_ms"] < row["wheels_p50_ms"]
    assert row["wheels_samples"] == 6 and 0.0 < row["actuation_p50_ms"] <= row["actuation_max_ms"]
    assert row["actuation_max_ms"] <= row["latency_bound_ms"] + row["control_period_ms"] + 1e-6


def test_the_wheels_stop_within_the_last_moving_tick_interpolated() -> None:
    t = np.arange(8) * 0.02
    x = np.array([0.0, 0.1, 0.2, 0.3, 0.35, 0.35, 0.35, 0.4])  # half a tick's way, then still
    poses = np.stack([x, np.zeros(8), np.zeros(8)], axis=1)
    assert wheels_stopped(t, poses, after=0.02) == pytest.approx(0.07)  # half of (0.06, 0.08]
    assert wheels_stopped(t, poses, after=0.08) == pytest.approx(0.08)  # no interval to read
    assert wheels_stopped(t, poses, after=0.11) is None  # moving again to the end
