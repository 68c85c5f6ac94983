"""``parkfleet bench sim`` runs, reports the documented schema and times real work (no timing
asserts): the plain loop does the simulator's job, every robot stays active, peers interact."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fleet.bench import sim as bench_sim
from fleet.cli.main import main
from fleet.core.simulate import simulate

ROW_KEYS = {
    "scene",
    "robots",
    "steps_per_s",
    "cpu_steps_per_s",
    "ratio_vs_loop",
    "loop_steps_per_s",
    "cpu_ratio_vs_loop",
}


def test_quick_bench_json_has_the_documented_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sim", "--quick", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) == {"rows"}
    assert [(row["scene"], row["robots"]) for row in report["rows"]] == [
        ("independent", 1),
        ("independent", 10),
        ("peers", 4),
        ("peers+filter", 4),
    ]
    for row in report["rows"]:
        assert set(row) == ROW_KEYS
        assert isinstance(row["robots"], int)
        for key in ROW_KEYS - {"scene", "robots"}:
            assert isinstance(row[key], float) and math.isfinite(row[key]) and row[key] > 0


def test_quick_bench_prints_a_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sim", "--quick"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:4] == ["scene", "robots", "steps", "robot-steps/s"]
    assert [line.split()[:2] for line in lines[1:5]] == [
        ["independent", "1"],
        ["independent", "10"],
        ["peers", "4"],
        ["peers+filter", "4"],
    ]
    assert "target at N = 10 000" in lines[-2]
    share = float(lines[-1].split(":")[1].split("x")[0])  # "peers+filter / peers: 0.58x ..."
    rates = {line.split()[0]: float(line.split()[3].replace(",", "")) for line in lines[3:5]}
    assert share == pytest.approx(rates["peers+filter"] / rates["peers"], abs=0.006)


def test_ratios_are_against_the_loop_of_the_same_scene_in_the_same_run() -> None:
    report = bench_sim.quick_bench()
    for row in report.rows:
        assert row.ratio_vs_loop == pytest.approx(row.steps_per_s / row.loop_steps_per_s)
        assert row.cpu_ratio_vs_loop > 0
    independent = {r.loop_steps_per_s for r in report.rows if r.scene == "independent"}
    assert len(independent) == 1  # one loop measurement for the whole scene


@pytest.mark.parametrize("peers", [False, True])
def test_the_plain_loop_does_the_simulators_job(peers: bool) -> None:
    """A fair baseline computes the same closed loop (same final poses and metrics)."""
    fleet = bench_sim.random_fleet(6, seed=5, peers=peers)
    steps = 150
    loop = bench_sim.plain_loop(fleet, steps)
    batch = simulate(fleet.problem(), max_time=steps * 0.01)
    assert batch.steps == steps and not batch.done.any()
    np.testing.assert_allclose(np.array(loop.poses), batch.final_pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose(loop.effort, batch.control_effort, rtol=1e-9)
    np.testing.assert_allclose(loop.distance, batch.distance, rtol=1e-9)


def test_timed_problems_keep_every_robot_active() -> None:
    """The benchmark's tolerances are never reached, so every simulated step is real work."""
    problem = bench_sim.random_fleet(200, seed=3).problem()
    result = simulate(problem, max_time=2000 * 0.01)
    assert result.steps == 2000 and not result.done.any()
    assert bench_sim._active_robot_steps(result) == 200 * 2000


def test_every_pair_of_the_peer_scene_interacts_at_every_step() -> None:
    fleet = bench_sim.random_fleet(bench_sim.PEER_ROBOTS, peers=True)
    result = simulate(fleet.problem(), max_time=2000 * 0.01, record=True, record_every=50)
    assert result.trajectory is not None and not result.done.any()
    poses = result.trajectory.poses
    gaps = np.hypot(
        poses[:, :, None, 0] - poses[:, None, :, 0], poses[:, :, None, 1] - poses[:, None, :, 1]
    )
    assert gaps.max() < bench_sim.PEER_RADIUS
    assert np.abs(result.control_effort).min() > 0  # wheel-limited, still moving


def test_step_counts_are_clamped() -> None:
    assert bench_sim.steps_for(1, 20_000_000, 200, 2_000) == 2_000
    assert bench_sim.steps_for(10_000, 20_000_000, 200, 2_000) == 2_000
    assert bench_sim.steps_for(100_000, 20_000_000, 200, 2_000) == 200
