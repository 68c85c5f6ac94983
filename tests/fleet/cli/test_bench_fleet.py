"""``parkfleet bench fleet`` as a user runs it, on the navground peers (no Zenoh needed)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet.bench.scenarios import dump_scenarios, swap
from fleet.cli.main import main

REQUIRED = {
    "scenario", "robots", "policy", "success_rate", "collisions", "min_separation_m",
    "makespan_s", "path_ratio", "deadlocks", "plan_p50_ms", "plan_p99_ms", "seed",
}  # fmt: skip

pytest.importorskip("navground")


def test_json_rows_plots_and_progress_from_a_scenario_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "mine.json"
    path.write_text(dump_scenarios([swap(2, "right"), swap(2, "left")]))
    code = main(
        ["bench", "fleet", "--scenario-file", str(path), "--scenario", "*-left",
         "--policy", "orca", "--policy", "hl", "--json", "--plots", str(tmp_path / "png")]
    )  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0
    data = json.loads(out)
    assert [(r["scenario"], r["policy"]) for r in data["rows"]] == [
        ("swap-2-left", "orca"),
        ("swap-2-left", "hl"),
    ]
    for row in data["rows"]:
        assert row.keys() >= REQUIRED
        assert row["success_rate"] == 1.0 and row["collisions"] == 0 and row["plan_p50_ms"] is None
    assert "2/2 swap-2-left" in err  # progress lines go to stderr with --json
    assert sorted(p.name for p in (tmp_path / "png").iterdir()) == [
        "swap-2-left--hl.png",
        "swap-2-left--orca.png",
    ]
    saved = tmp_path / "run.json"
    saved.write_text(out)
    # the tables of docs/benchmarks.md
    assert main(["bench", "fleet", "--from-json", str(saved)]) == 0
    tables = capsys.readouterr().out
    orca, hl = (f"{r['makespan_s']:.0f} s" for r in data["rows"])
    assert f"| swap-2 | 2 | 1 | 100% · 0 · {orca} | 100% · 0 · {hl} |" in tables


def test_bad_requests_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "fleet", "--scenario", "nothing-*", "--policy", "orca"]) == 2
    assert "no scenario matches" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text('{"name": "x", "robots": []}')
    assert main(["bench", "fleet", "--scenario-file", str(bad)]) == 2
    assert "robots: List should have at least 1 item" in capsys.readouterr().err
    assert main(["bench", "fleet", "--from-json", str(bad)]) == 2
    assert "not a bench fleet --json output" in capsys.readouterr().err


def _orca_on_swap_2_left(tmp_path: Path) -> list[str]:
    """The arguments of a JSON run of ORCA on a scenario file holding swap-2-left."""
    path = tmp_path / "mine.json"
    path.write_text(dump_scenarios([swap(2, "left")]))
    return ["bench", "fleet", "--scenario-file", str(path), "--policy", "orca", "--json"]


def test_disturbance_seeds_run_every_policy_on_each_set_of_the_same_robots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = _orca_on_swap_2_left(tmp_path)
    assert main([*args, "--disturbance-seeds", "2"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [(r["policy"], r["disturbance_seed"]) for r in rows] == [("orca", 0), ("orca", 1)]
    assert rows[0]["makespan_s"] != rows[1]["makespan_s"]  # other disturbances, other run
    assert main(args) == 0  # seed 0 again: the same robots, the same run
    (again,) = json.loads(capsys.readouterr().out)["rows"]
    assert again["makespan_s"] == rows[0]["makespan_s"]
    assert main([*args, "--perfect", "--disturbance-seeds", "2"]) == 0
    perfect = json.loads(capsys.readouterr().out)["rows"]
    assert perfect[0]["stops_per_trip"] == 0.0 and perfect[0]["cusps_per_trip"] == 0.0


def test_repeats_run_each_seed_again_and_navgrounds_peers_repeat_exactly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = _orca_on_swap_2_left(tmp_path)
    assert main([*args, "--disturbance-seeds", "2", "--repeats", "2"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [(r["disturbance_seed"], r["repeat"]) for r in rows] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert rows[0]["makespan_s"] == rows[1]["makespan_s"] != rows[2]["makespan_s"]
    assert rows[2]["makespan_s"] == rows[3]["makespan_s"]
    saved = tmp_path / "run.json"
    saved.write_text(json.dumps({"rows": rows}))
    assert main(["bench", "fleet", "--from-json", str(saved)]) == 0
    assert "| swap-2 | 2 | 4 |" in capsys.readouterr().out  # four runs in the family's row
