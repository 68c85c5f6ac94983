"""The fleet benchmark's own machinery, end to end: real service, real sim agents, Zenoh.

(a) three robots whose paths cross, under ``auto``, on noisy robots (pose noise ~1 cm and
0.5 deg, 5 % wheel noise and a 2 % wheel bias), submitted through the service over Zenoh:
every task succeeds and no two robots ever touch -- judged on the sim's time-aligned true
poses (``parkfleet sim --trace``), not on states that happened to be delivered. Without
the benchmark's 50-150 ms command latency: with it, today's agents touch on such
crossings (see docs/benchmarks.md), which is for the planner and the controller to fix.
(b) SIGTERM stops a running ``parkfleet bench fleet`` with its sim child, its navground
worker and its sessions.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support import child_pids, command_line, is_alive, wait_for

from fleet.bench.fleet import BenchOptions, run_fleet_bench
from fleet.bench.scenarios import RobotSpec, Scenario
from fleet.io.trace import read_header, read_trace

pytestmark = pytest.mark.integration

#: Noisy robots: the benchmark's disturbances but the command latency.
NOISY = (
    "--pose-noise", "0.01", "--heading-noise", "0.5",
    "--actuation-noise", "0.05", "--wheel-bias", "0.02",
)  # fmt: skip

#: Three paths that cross pairwise at three different points.
CROSSING = Scenario(
    name="crossing-3",
    robots=[
        RobotSpec(start=(-5.0, 1.0, 0.0), goal=(5.0, 1.0, 0.0)),
        RobotSpec(start=(-1.0, -5.0, 1.5708), goal=(-1.0, 5.0, 1.5708)),
        RobotSpec(start=(5.0, -4.0, 2.38), goal=(-4.0, 4.5, 2.38)),
    ],
    time_limit_s=180.0,
)


def test_three_noisy_robots_crossing_under_auto_all_park_without_touching(
    tmp_path: Path,
) -> None:
    options = BenchOptions(disturbances=NOISY, traces=tmp_path)
    (row,) = run_fleet_bench([CROSSING], ["auto"], options)
    assert row.success_rate == 1.0 and row.arrived == 3
    assert row.collisions == 0
    assert row.min_separation_m is not None and row.min_separation_m > 0.4
    assert row.plan_p50_ms is not None  # the service really planned (auto)
    # the trace holds every tick of the run, in order, without gaps, until all had parked
    chunks = list(read_trace(tmp_path / "crossing-3--auto.trace"))
    t = np.concatenate([c.t for c in chunks])
    period = read_header(tmp_path / "crossing-3--auto.trace").period_s
    np.testing.assert_allclose(np.diff(t), period, rtol=1e-6)
    assert t[-1] - t[0] >= row.makespan_s - period
    # and the plans log: one JSON line per plan the service made, which assigned every task
    (log,) = tmp_path.glob("*-0-auto/plans.jsonl")  # the run (the warm-up has its own)
    plans = [json.loads(line) for line in log.read_text().splitlines()]
    assert plans and all(p["robots"] == 3 and p["took_s"] > 0 for p in plans)
    assert sum(p["actions"].get("assign", 0) for p in plans) >= 3
    assert [p["at"] for p in plans] == sorted(p["at"] for p in plans)


def test_sigterm_stops_the_bench_its_sim_child_and_its_navground_worker() -> None:
    bench = subprocess.Popen(
        [sys.executable, "-m", "fleet.cli", "bench", "fleet", "--scenario", "swap-4-right",
         "--policy", "cw", "--policy", "socialforce", "--time-limit", "600"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=os.environ | {"PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    try:
        wait_for(
            lambda: any("fleet.cli sim" in command_line(p) for p in child_pids(bench.pid)),
            60.0,
            "the sim child",
        )
        children = child_pids(bench.pid)  # the sim, the navground worker (spawned)
        assert any("multiprocessing" in command_line(p) for p in children)
        bench.send_signal(signal.SIGTERM)
        _, err = bench.communicate(timeout=60)
        assert bench.returncode == 130, err.decode()
        # multiprocessing's resource tracker (a child too) exits once it reads the bench's
        # end of its pipe: shortly after the bench, not before it
        wait_for(
            lambda: not [p for p in children if is_alive(p)], 30.0, "the bench's children to exit"
        )
    finally:
        if bench.poll() is None:
            bench.kill()
            bench.communicate(timeout=10)
