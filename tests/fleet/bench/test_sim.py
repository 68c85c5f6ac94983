"""``parkfleet bench sim`` runs and reports the documented schema (no timing asserts)."""

from __future__ import annotations

import json
import math

import pytest

from fleet.bench import sim as bench_sim
from fleet.cli.main import main
from fleet.core.simulate import simulate


def test_quick_bench_json_has_the_documented_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sim", "--quick", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) == {"rows"}
    assert [row["robots"] for row in report["rows"]] == [1, 10]
    for row in report["rows"]:
        assert set(row) == {"robots", "steps_per_s", "ratio_vs_loop"}
        assert isinstance(row["robots"], int)
        for key in ("steps_per_s", "ratio_vs_loop"):
            assert isinstance(row[key], float) and math.isfinite(row[key]) and row[key] > 0


def test_quick_bench_prints_a_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sim", "--quick"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["robots", "steps", "robot-steps/s", "vs", "loop", "(wall", "clock)"]
    assert [line.split()[0] for line in lines[1:3]] == ["1", "10"]
    assert "plain Python loop" in lines[3]


def test_ratios_are_against_the_loop_measured_in_the_same_run() -> None:
    report = bench_sim.quick_bench()
    for row in report.rows:
        assert row.ratio_vs_loop == pytest.approx(row.steps_per_s / report.loop_steps_per_s)


def test_timed_problems_keep_every_robot_active() -> None:
    """The benchmark's tolerances are never reached, so every simulated step is real work."""
    problem = bench_sim.random_fleet(200, seed=3).problem()
    result = simulate(problem, max_time=2000 * 0.01)
    assert result.steps == 2000 and not result.done.any()


def test_finished_robots_count_only_their_active_steps() -> None:
    assert bench_sim._active_robot_steps([True, False, True], [0.01, math.nan, 0.25], 40) == (
        1 + 40 + 25
    )


def test_step_counts_are_clamped() -> None:
    assert bench_sim.steps_for(1, 20_000_000, 200, 2_000) == 2_000
    assert bench_sim.steps_for(10_000, 20_000_000, 200, 2_000) == 2_000
    assert bench_sim.steps_for(100_000, 20_000_000, 200, 2_000) == 200
