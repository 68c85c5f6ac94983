"""``parkfleet bench plan`` runs and reports the documented schema (no timing asserts)."""

from __future__ import annotations

import json
import math

import pytest

from fleet.cli.main import main

LATENCY = {
    "robots", "seeds", "decisions", "plan_p50_ms", "plan_p99_ms", "cpu_p50_ms", "cpu_p99_ms",
    "rollouts_p50", "rollouts_max", "clusters_mean", "clusters_max", "success_rate",
    "collisions", "min_separation_m",
}  # fmt: skip
QUALITY = {
    "scenario", "robots", "policy", "success_rate", "collisions", "min_separation_m",
    "makespan_s", "path_ratio",
}  # fmt: skip


def test_quick_bench_json_has_the_documented_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "plan", "--quick", "--quality", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) == {"latency", "quality"}
    (row,) = report["latency"]
    assert set(row) == LATENCY and row["robots"] == 4 and row["seeds"] == 1
    assert row["decisions"] >= 2 and row["rollouts_max"] >= 1 and row["clusters_max"] >= 1
    assert row["plan_p99_ms"] >= row["plan_p50_ms"] > 0
    assert row["success_rate"] == 1.0 and row["collisions"] == 0
    assert row["min_separation_m"] >= 0.5
    assert {(q["scenario"], q["policy"]) for q in report["quality"]} == {
        (s, p) for s in ("swap-2-right", "swap-2-left") for p in ("auto", "cw", "ccw")
    }
    for q in report["quality"]:
        assert set(q) == QUALITY
        if q["policy"] == "auto":
            assert q["success_rate"] == 1.0 and q["collisions"] == 0
            assert q["min_separation_m"] >= 0.5 and math.isfinite(q["makespan_s"])


def test_bad_sizes_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "plan", "--robots", "0"]) == 2
    assert "at least 1" in capsys.readouterr().err


def test_a_stream_longer_than_the_default_limit_is_run_to_its_end(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The run lasts until its last task has arrived and had time to park: a stream of 4
    tasks 200 s apart (the last arrives after the closed loop's default 240 s) parks all."""
    from fleet.bench import plan as bench_plan

    monkeypatch.setattr(bench_plan, "STREAM_GAP_S", 200.0)
    assert max(bench_plan.arrivals(4, 1)) > 240.0
    row = bench_plan.latency(4, [1])
    assert row.success_rate == 1.0 and row.collisions == 0
