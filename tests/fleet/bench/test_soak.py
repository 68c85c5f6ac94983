"""``parkfleet bench soak``: the slope with its noise, the store check, and a short real run."""

from __future__ import annotations

import asyncio
import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support import child_pids, command_line, is_alive, wait_for

from fleet.bench.soak import Tally, call, check_store, slope
from fleet.cli.main import main
from fleet.core.tasks import Task, TaskRequest, TaskStatus
from fleet.core.wire import Pose
from fleet.service.store import SqliteTaskStore


@given(
    a=st.floats(-100, 100),
    b=st.floats(-10, 10),
    noise=st.lists(st.floats(-1, 1), min_size=12, max_size=12),
)
def test_slope_recovers_a_line_within_its_noise(a: float, b: float, noise: list[float]) -> None:
    t = [float(k) for k in range(12)]
    fit = slope(t, [a + b * x + e for x, e in zip(t, noise, strict=True)])
    # noise within ±1 moves a least-squares slope over t = 0..11 by at most 36/143
    assert abs(fit.per_min - b) <= 36 / 143 + 1e-6
    assert fit.noise <= 1.0 + 1e-6


def test_slope_of_a_steady_climb_is_not_flat_and_of_noise_is() -> None:
    t = [float(k) for k in range(10)]
    assert not slope(t, [100 + 2.0 * x + 0.1 * (-1) ** x for x in t]).flat
    assert slope(t, [100 + 0.5 * (-1) ** x for x in t]).flat
    assert math.isnan(slope([0.0, 1.0], [1.0, 2.0]).per_min)  # too few points to say


def _task(task_id: str) -> Task:
    return Task(id=task_id, request=TaskRequest(goal=Pose(x=0, y=0)), created_at=1, updated_at=1)


def test_store_check_finds_lost_open_and_twice_finished_tasks(tmp_path: Path) -> None:
    db = tmp_path / "parkfleet.db"
    store = SqliteTaskStore(db)
    for task_id in ("done", "open", "twice"):
        store.save_new(_task(task_id), None)
    for task_id in ("done", "twice", "twice"):
        store.save(_task(task_id).model_copy(update={"status": TaskStatus.CANCELLED}), "x")
    store.close()
    check = check_store(db, ["done", "open", "twice", "ghost"])
    assert (check.lost, check.not_final, check.final_transitions_not_one) == (1, 1, 3)
    assert not check.ok
    assert check_store(db, ["done"]).ok
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT COUNT(*) FROM task_history").fetchone()[0] == 6
    conn.close()


@pytest.mark.integration
def test_a_short_soak_runs_and_loses_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["bench", "soak", "--minutes", "0.3", "--robots", "4", "--groups", "2"]
    argv += ["--sample-s", "6", "--tasks-per-s", "3", "--event-clients", "2", "--json"]
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert report["check"]["lost"] == 0 and report["check"]["accepted"] > 0
    assert report["tally"]["server_errors"] == 0 and report["tally"]["unexpected"] == {}
    assert len(report["samples"]) >= 3
    assert all(s["rss_mb"] > 0 and s["open_fds"] > 0 for s in report["samples"])


def test_a_request_without_answer_is_counted_not_fatal() -> None:
    def stall(request: httpx.Request) -> httpx.Response:
        if request.url.path == "/tasks":
            raise httpx.ReadTimeout("no answer", request=request)
        return httpx.Response(200, json=[])

    async def two_calls() -> tuple[httpx.Response | None, httpx.Response | None]:
        tally = Tally()
        transport = httpx.MockTransport(stall)
        async with httpx.AsyncClient(base_url="http://x", transport=transport) as client:
            stalled = await call(client, tally, "GET", "/tasks", "/tasks")
            answered = await call(client, tally, "GET", "/healthz", "/healthz")
        assert tally.timeouts == {"GET /tasks": 1}
        return stalled, answered

    stalled, answered = asyncio.run(two_calls())
    assert stalled is None and answered is not None and answered.status_code == 200


@pytest.mark.integration
def test_sigterm_stops_the_soak_with_its_server_and_robots() -> None:
    soak = subprocess.Popen(
        [sys.executable, "-m", "fleet.cli", "bench", "soak", "--minutes", "30",
         "--robots", "4", "--groups", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=os.environ | {"PYTHONUNBUFFERED": "1"},
    )  # fmt: skip

    def sims() -> list[int]:
        return [p for p in child_pids(soak.pid) if "fleet.cli sim" in command_line(p)]

    try:
        wait_for(lambda: len(sims()) == 2, 120.0, "the soak's two robot groups")
        children = child_pids(soak.pid)
        assert any("fleet.cli serve" in command_line(p) for p in children)
        soak.send_signal(signal.SIGTERM)
        _, err = soak.communicate(timeout=60)
        assert soak.returncode == 130, err.decode()
        wait_for(lambda: not [p for p in children if is_alive(p)], 30.0, "the children to exit")
    finally:
        if soak.poll() is None:
            soak.kill()
            soak.communicate(timeout=10)
