"""``parkfleet bench api`` against a real server, planning in its own process."""

from __future__ import annotations

import json

import pytest

from fleet.cli.main import main


def test_a_server_planning_in_its_own_process_stores_and_answers_every_post(
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = ["bench", "api", "--requests", "20", "--concurrency", "4", "--robots", "2"]
    assert main([*args, "--planner", "process", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["planner"] == "process"
    assert row["created"] == 20 and row["statuses"] == {"201": 20}
    assert row["p99_ms"] >= row["p50_ms"] > 0


def test_an_unknown_planner_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "api", "--planner", "gpu"])
    assert exit_.value.code == 2
    assert "invalid choice: 'gpu'" in capsys.readouterr().err
