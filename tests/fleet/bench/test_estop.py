"""``parkfleet bench estop`` runs end to end and reports consistent rows (no timing asserts)."""

from __future__ import annotations

import json
import subprocess

import pytest

from fleet.io.processes import parkfleet_command

pytestmark = pytest.mark.integration


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
