"""``parkfleet tune``: scoring, the search, the Pareto front and the command."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.params import RobotProfile
from fleet.core.simulate import BatchProblem, SimResult, simulate
from fleet.core.types import FloatArray
from fleet.paper.scenarios import SCENARIOS
from fleet.paper.tune import (
    FAIL_PENALTY,
    YARD_MAX_KX,
    TuneTarget,
    Weights,
    case_target,
    pareto_front,
    score,
    tune,
    yard_target,
    yard_trips,
)


def _run_alone(target: TuneTarget, gains: FloatArray, record: bool = False) -> SimResult:
    """The target's trips under one gain triple, simulated on their own (not via score)."""
    problem = BatchProblem.build(
        target.starts,
        target.goals,
        gains,
        target.law,
        tolerance=target.tolerance,
        profile=target.profile,
    )
    return simulate(problem, dt=target.dt, max_time=target.max_time, record=record)


def test_score_is_one_batch_of_candidates_times_trips() -> None:
    target = yard_target("ccw", trips=3, seed=5)
    gains = np.array([[1.0, 2.0, 1.5], [2.0, 20.0, 5.0]])
    scores = score(target, gains)
    for i, row in enumerate(gains):
        alone = _run_alone(target, row)
        times = np.where(alone.done, alone.time, target.max_time)
        turns = np.abs(alone.final_pose[:, 2] - target.starts[:, 2]) / (2.0 * math.pi)
        assert scores.distance[i] == pytest.approx(alone.distance.mean())
        assert scores.effort[i] == pytest.approx(alone.control_effort.mean())
        assert scores.time[i] == pytest.approx(times.mean())
        w = target.weights
        expected = (
            w.effort * alone.control_effort.mean()
            + w.distance * alone.distance.mean()
            + w.time * times.mean()
            + w.turns * turns.mean()
            + FAIL_PENALTY * (1.0 - alone.done.mean())
        )
        assert scores.cost[i] == pytest.approx(expected)


def test_search_beats_the_papers_gains_within_the_wheel_limit() -> None:
    target = case_target("I", "cw")
    result = tune(target, seed=1, popsize=8, generations=12)
    assert result.beats_reference  # less effort and less distance than Table 4's gains
    assert result.reference_scores is not None
    assert result.best_scores["cost"] < result.reference_scores["cost"]
    # The wheel limit: run the best gains again, recorded, and look at every wheel speed.
    scenario = SCENARIOS["I"]
    profile = RobotProfile()
    run = simulate(
        BatchProblem.build(
            scenario.start,
            scenario.goal,
            result.best,
            "cw",
            tolerance=scenario.tolerance,
            profile=profile,
        ),
        record=True,
        max_time=target.max_time,
    )
    assert run.trajectory is not None and run.done[0]
    right, left = run.trajectory.wheel_speeds(profile.wheel_radius, profile.half_axle)
    peak = float(np.max(np.abs(np.concatenate([right, left]))))
    assert peak <= profile.max_wheel_speed * (1 + 1e-12)
    assert peak > 0.9 * profile.max_wheel_speed  # the limit binds: it is really in the loop
    # Every candidate scored lies within the bounds of the search.
    lo = np.array([b[0] for b in target.bounds])
    hi = np.array([b[1] for b in target.bounds])
    assert (
        (result.evaluated_gains >= lo * (1 - 1e-12)) & (result.evaluated_gains <= hi * (1 + 1e-12))
    ).all()


def test_yard_target_caps_kx_and_uses_the_fleet_robot() -> None:
    target = yard_target("cw", trips=4, max_kx=2.0)
    assert target.bounds[0] == (0.1, 2.0)
    assert target.profile == RobotProfile() and math.isfinite(target.profile.max_wheel_speed)
    assert target.reference == SCENARIOS["first"].gains["cw"]
    for law in ("ccw", "cw"):
        assert yard_target(law, trips=1).bounds[0][1] == SCENARIOS["first"].gains[law].kx
        assert YARD_MAX_KX[law] == SCENARIOS["first"].gains[law].kx


@settings(max_examples=30)
@given(count=st.integers(1, 40), seed=st.integers(0, 2**16))
def test_yard_trips_stay_in_the_yard_and_apart(count: int, seed: int) -> None:
    starts, goals = yard_trips(count, seed, half=5.0, spacing=1.5)
    assert starts.shape == goals.shape == (count, 3)
    assert (np.abs(starts[:, :2]) <= 5.0).all() and (np.abs(goals[:, :2]) <= 5.0).all()
    assert (np.hypot(*(starts[:, :2] - goals[:, :2]).T) >= 1.5).all()
    assert (np.abs(starts[:, 2]) <= math.pi).all()
    again = yard_trips(count, seed, half=5.0, spacing=1.5)
    np.testing.assert_array_equal(again[0], starts)


points = st.lists(
    st.tuples(st.floats(0, 10, allow_nan=False), st.floats(0, 10, allow_nan=False)),
    min_size=1,
    max_size=40,
)


@given(pts=points)
def test_pareto_front_is_exactly_the_undominated_points(pts: list[tuple[float, float]]) -> None:
    e = np.array([p[0] for p in pts])
    d = np.array([p[1] for p in pts])
    front = set(pareto_front(e, d).tolist())
    for i in range(len(pts)):
        dominated = any(
            e[j] <= e[i] and d[j] <= d[i] and (e[j] < e[i] or d[j] < d[i]) for j in range(len(pts))
        )
        if i in front:
            assert not dominated
        elif not dominated:  # an undominated point left out must duplicate a front point
            assert any(e[j] == e[i] and d[j] == d[i] for j in front)


def test_weights_must_be_non_negative_and_not_all_zero() -> None:
    with pytest.raises(ValueError):
        Weights(effort=0.0, distance=0.0, time=0.0)
    with pytest.raises(ValueError):
        Weights(effort=-1.0)


def test_cli_prints_json_and_writes_the_pareto_plot(tmp_path: Path) -> None:
    out = tmp_path / "front.png"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "fleet.cli",
            "tune",
            "I",
            "--law",
            "ccw",
            "--generations",
            "2",
            "--popsize",
            "3",
            "--w-time",
            "0.5",
            "-o",
            str(out),
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert report["target"] == "I" and report["law"] == "ccw"
    assert set(report["best"]) == {"kx", "ky", "ktheta"}
    assert report["reference"] == SCENARIOS["I"].gains["ccw"].model_dump()
    assert report["candidates"] >= 9 and report["plot"] == str(out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_rejects_a_negative_weight(capsys: pytest.CaptureFixture[str]) -> None:
    from fleet.cli.main import main

    with pytest.raises(SystemExit) as exc:
        main(["tune", "I", "--law", "cw", "--w-time", "-1"])
    assert exc.value.code == 2
    assert "must be >= 0" in capsys.readouterr().err


@pytest.mark.parametrize("law", ["ccw", "cw"])
def test_turns_are_each_trips_whole_rotation_in_the_laws_sense(law: str) -> None:
    target = yard_target(law, trips=6, seed=11)  # type: ignore[arg-type]
    gains = np.array([[2.0, 100.0, 10.0], [2.0, 3.0, 3.0]])
    scores = score(target, gains)
    for i, row in enumerate(gains):
        run = _run_alone(target, row, record=True)
        assert run.trajectory is not None and run.done.all()
        omega = run.trajectory.controls[..., 1]
        assert (omega >= 0.0).all() if law == "ccw" else (omega <= 0.0).all()
        whole = np.abs(omega).sum(axis=0) * target.dt / (2.0 * math.pi)  # [rev] per trip
        assert scores.turns[i] == pytest.approx(whole.mean(), rel=1e-9, abs=1e-12)
        # At least the turn the law's sense needs, less the heading tolerance.
        need = (target.goals[:, 2] - target.starts[:, 2]) * (1.0 if law == "ccw" else -1.0)
        least = (np.mod(need, 2.0 * math.pi) - target.tolerance.heading) / (2.0 * math.pi)
        assert (whole >= least - 1e-9).all()
    # The strong y_e^2 term spins: the time-first gains turn more than the gentle ones.
    assert scores.turns[0] > scores.turns[1]
