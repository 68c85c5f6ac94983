"""Two `parkfleet serve --store postgresql://...` on one real PostgreSQL: a leader and a
standby, real HTTP; the standby answers writes with 503 and the leader's address, serves
reads from the store, and takes over when the leader is SIGKILLed."""

from __future__ import annotations

import subprocess
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import httpx
import pytest
from support import wait_for

from fleet.io.processes import ServerProcess, parkfleet_command, running_server

pytestmark = pytest.mark.integration

TASK = {"goal": {"x": 2.0, "y": 1.0, "theta": 0.0}}


def _health(url: str) -> dict[str, Any]:
    return dict(httpx.get(f"{url}/healthz", timeout=10).json())


def _roles(servers: list[ServerProcess]) -> dict[str, str]:
    return {s.url: _health(s.url)["role"] for s in servers}


def test_standby_answers_writes_with_503_serves_reads_and_takes_over(
    postgres_dsn: str, tmp_path: Path
) -> None:
    with ExitStack() as stack:
        servers = [
            stack.enter_context(
                running_server(
                    tmp_path / f"data{k}",
                    "--store",
                    postgres_dsn,
                    stderr=stack.enter_context((tmp_path / f"serve{k}.log").open("w")),
                )
            )
            for k in range(2)
        ]
        wait_for(lambda: sorted(_roles(servers).values()) == ["leader", "standby"], 60, "roles")
        roles = _roles(servers)
        leader = next(s for s in servers if roles[s.url] == "leader")
        standby = next(s for s in servers if roles[s.url] == "standby")
        wait_for(lambda: _health(standby.url)["leader"] == leader.url, 60, "standby sees leader")
        health = _health(standby.url)
        assert (health["store"], health["term"], health["robots"]) == ("postgresql", 1, 0)

        refused = httpx.post(f"{standby.url}/tasks", json=TASK, timeout=10)
        assert refused.status_code == 503
        assert refused.headers["X-Parkfleet-Leader"] == leader.url
        assert leader.url in refused.json()["detail"] and refused.headers["Retry-After"] == "1"

        created = httpx.post(f"{leader.url}/tasks", json=TASK, timeout=10)
        assert created.status_code == 201, created.text
        task_id = created.json()["id"]
        read = httpx.get(f"{standby.url}/tasks/{task_id}", timeout=10)
        assert read.status_code == 200 and read.json()["status"] == "queued"

        leader.process.kill()  # SIGKILL: its lock goes when its connection closes
        leader.process.wait(timeout=30)
        wait_for(lambda: _health(standby.url)["role"] == "leader", 60, "the standby taking over")
        health = _health(standby.url)
        assert health["term"] == 2 and health["leader"] == standby.url
        assert health["counters"]["tasks_recovered"] == 1  # the ledger, rebuilt from the store
        again = httpx.get(f"{standby.url}/tasks/{task_id}", timeout=10)
        assert again.status_code == 200 and again.json()["status"] == "queued"
        other = {"goal": {"x": -2.0, "y": -1.0, "theta": 0.0}}  # the first goal is taken
        assert httpx.post(f"{standby.url}/tasks", json=other, timeout=10).status_code == 201


def test_serve_with_postgresql_unreachable_exits_2_naming_the_server(tmp_path: Path) -> None:
    dsn = "postgresql://nobody:secret@127.0.0.1:9/nowhere"  # port 9 (discard): nobody listens
    done = subprocess.run(
        parkfleet_command("serve", "--port", "0", "--zenoh-listen", "tcp/127.0.0.1:0",
                          "--data-dir", str(tmp_path), "--store", dsn),
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "PostgreSQL unreachable at postgresql://127.0.0.1:9/nowhere" in done.stderr
    assert "secret" not in done.stderr
