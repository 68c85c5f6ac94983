"""``parkfleet bench on-state`` runs both workloads and reports the documented schema."""

from __future__ import annotations

import json
import math

import pytest

from fleet.bench.on_state import run_on_state
from fleet.cli.main import main


def test_json_has_the_documented_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "on-state", "--robots", "9", "--rounds", "10", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["workload"] for r in rows] == ["idle", "driving"]
    for r in rows:
        assert set(r) == {
            "workload",
            "robots",
            "states",
            "states_per_cpu_s",
            "us_per_state",
            "events",
        }
        assert (r["robots"], r["states"]) == (9, 90)
        assert math.isfinite(r["states_per_cpu_s"]) and r["states_per_cpu_s"] > 0
        assert r["us_per_state"] == pytest.approx(1e6 / r["states_per_cpu_s"])


def test_robot_events_are_throttled_as_in_service() -> None:
    # 50 rounds at 50 Hz = 1 s: at most one event per robot per 0.1 s (about 10 each, not
    # 50); 0.1 s is 5 periods of 0.02 s, which add up to a hair less, hence every 6th state.
    row = run_on_state("idle", robots=4, rounds=50)
    assert 4 * 8 <= row.events <= 4 * 11
    driving = run_on_state("driving", robots=4, rounds=50)
    assert driving.states == 200


def test_bad_arguments_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "on-state", "--robots", "0"]) == 2
    with pytest.raises(ValueError, match="unknown workload"):
        run_on_state("sprinting", robots=1, rounds=1)
