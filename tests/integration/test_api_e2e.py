"""End to end as a user runs it: `parkfleet serve` and `parkfleet sim` subprocesses, HTTP.

Every server binds free ports (API ``--port 0``, Zenoh ``tcp/127.0.0.1:0``) and a fresh
data directory; every process is stopped in a ``finally``.
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import sqlite3
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from support import wait_for

from fleet.io.processes import ServerProcess, running_server, sim_command, terminate

pytestmark = pytest.mark.integration

SIM_TIME_SCALE = "4"
BIG_YARD = {"PARKFLEET_YARD": json.dumps([-100, 100, -100, 100])}


@pytest.fixture
def server(tmp_path: Path) -> Iterator[ServerProcess]:
    with (
        (tmp_path / "serve.log").open("w") as log,
        running_server(tmp_path / "data", stderr=log) as proc,
    ):
        yield proc


def start_sim(endpoint: str, robots: int, log: Path) -> subprocess.Popen[bytes]:
    cmd = sim_command(endpoint, robots, time_scale=float(SIM_TIME_SCALE))
    with log.open("w") as out:
        return subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=out)


def wait_status(client: httpx.Client, task_id: str, status: str, timeout: float = 90.0) -> Any:
    """The task once it reaches ``status`` (fails at once if it ends otherwise)."""
    task: Any = None

    def reached() -> bool:
        nonlocal task
        task = client.get(f"/tasks/{task_id}").json()
        assert task["status"] not in {"failed", "cancelled", "succeeded"} - {status}, task
        return bool(task["status"] == status)

    wait_for(reached, timeout, f"task {task_id} to reach {status}", poll=0.05)
    return task


def wait_robots(client: httpx.Client, n: int, timeout: float = 30.0) -> None:
    def joined() -> bool:
        return sum(r["status"] != "lost" for r in client.get("/robots").json()) >= n

    wait_for(joined, timeout, f"{n} robots to join", poll=0.05)


def test_task_reaches_succeeded_with_a_simulated_fleet(
    server: ServerProcess, tmp_path: Path
) -> None:
    sim = start_sim(server.zenoh_endpoint, 2, tmp_path / "sim.log")
    try:
        with httpx.Client(base_url=server.url, timeout=10) as client:
            wait_robots(client, 2)
            created = client.post("/tasks", json={"goal": {"x": 3.0, "y": 2.0, "theta": 1.57}})
            assert created.status_code == 201, created.text
            task = wait_status(client, created.json()["id"], "succeeded")
            assert task["robot_id"] is not None
            assert task["law"] in ("cw", "ccw")
            robot = client.get(f"/robots/{task['robot_id']}").json()
            assert abs(robot["pose"]["x"] - 3.0) < 0.15
            assert abs(robot["pose"]["y"] - 2.0) < 0.15
            assert client.get(f"/tasks/{task['id']}/path").json()
            again = client.post(f"/tasks/{task['id']}/cancel")
            assert again.status_code == 409
    finally:
        terminate(sim)


async def _collect_events(
    url: str, task_id_box: list[str], seen: list[tuple[str, Any]], listening: asyncio.Event
) -> None:
    async with (
        httpx.AsyncClient(base_url=url, timeout=None) as client,
        client.stream("GET", "/events") as response,
    ):
        assert response.headers["content-type"].startswith("text/event-stream")
        event = ""
        async for line in response.aiter_lines():
            listening.set()  # the first line comes after the server subscribed us
            if line.startswith("event: "):
                event = line[7:]
            elif line.startswith("data: "):
                data = json.loads(line[6:])
                seen.append((event, data))
                if (
                    event == "task"
                    and task_id_box
                    and data["id"] == task_id_box[0]
                    and data["status"] == "succeeded"
                ):
                    return


def test_events_stream_robot_states_and_task_changes(server: ServerProcess, tmp_path: Path) -> None:
    sim = start_sim(server.zenoh_endpoint, 1, tmp_path / "sim.log")
    try:
        with httpx.Client(base_url=server.url, timeout=10) as client:
            wait_robots(client, 1)

        async def scenario() -> list[tuple[str, Any]]:
            seen: list[tuple[str, Any]] = []
            box: list[str] = []
            listening = asyncio.Event()
            listener = asyncio.create_task(_collect_events(server.url, box, seen, listening))
            await asyncio.wait_for(listening.wait(), 30)
            async with httpx.AsyncClient(base_url=server.url) as client:
                r = await client.post("/tasks", json={"goal": {"x": -2.0, "y": 1.0}})
                box.append(r.json()["id"])
            await asyncio.wait_for(listener, 90)
            return seen

        seen = asyncio.run(scenario())
        statuses = [d["status"] for e, d in seen if e == "task"]
        assert statuses[0] == "queued" or "assigned" in statuses
        assert statuses[-1] == "succeeded"
        robot_frames = [d for e, d in seen if e == "robot"]
        assert robot_frames
        assert {"robot_id", "pose", "status", "task_id"} <= set(robot_frames[-1])
    finally:
        terminate(sim)


def test_accepted_tasks_survive_a_restart_and_resume(tmp_path: Path) -> None:
    data = tmp_path / "data"
    goals = [(2.0, 2.0), (-2.0, -2.0), (4.0, -3.0)]
    with (tmp_path / "serve1.log").open("w") as log, running_server(data, stderr=log) as first:
        with httpx.Client(base_url=first.url, timeout=10) as client:
            ids = [
                client.post("/tasks", json={"goal": {"x": x, "y": y}}).json()["id"]
                for x, y in goals
            ]
            cancelled = client.post(f"/tasks/{ids[2]}/cancel").json()
            assert cancelled["status"] == "cancelled"
            before = {t["id"]: t for t in client.get("/tasks").json()}
        assert first.stop() == 0  # SIGTERM: graceful
    with (
        (tmp_path / "serve2.log").open("w") as log,
        running_server(data, stderr=log) as second,
        httpx.Client(base_url=second.url, timeout=10) as client,
    ):
        after = {t["id"]: t for t in client.get("/tasks").json()}
        assert set(after) == set(before) == set(ids)
        assert after[ids[2]]["status"] == "cancelled"
        for task_id in ids[:2]:
            assert after[task_id]["goal"] == before[task_id]["goal"]
            assert after[task_id]["status"] in ("queued", "assigned")
        sim = start_sim(second.zenoh_endpoint, 2, tmp_path / "sim.log")
        try:
            for task_id in ids[:2]:  # resumed: robots get them after the restart
                wait_status(client, task_id, "succeeded")
        finally:
            terminate(sim)


async def _post_many(url: str, n: int, concurrency: int) -> list[httpx.Response]:
    side = 150
    bodies = [
        {"goal": {"x": -90.0 + 1.2 * (k % side), "y": -90.0 + 1.2 * (k // side)}} for k in range(n)
    ]
    todo = iter(bodies)
    responses: list[httpx.Response] = []

    async def client_loop() -> None:
        async with httpx.AsyncClient(base_url=url, timeout=60) as client:
            for body in todo:
                responses.append(await client.post("/tasks", json=body))

    await asyncio.gather(*(client_loop() for _ in range(concurrency)))
    return responses


def test_1000_concurrent_posts_are_all_stored(tmp_path: Path) -> None:
    data = tmp_path / "data"
    with (
        (tmp_path / "serve.log").open("w") as log,
        running_server(data, env=BIG_YARD, stderr=log) as srv,
    ):
        responses = asyncio.run(_post_many(srv.url, 1000, concurrency=50))
        # Kill -9: a 201 promises the task is on disk, not just in the server's memory.
        srv.process.send_signal(signal.SIGKILL)
        srv.process.wait(10)
    assert len(responses) == 1000
    assert {r.status_code for r in responses} == {201}, {r.status_code for r in responses}
    created = {r.json()["id"] for r in responses}
    assert len(created) == 1000
    with sqlite3.connect(data / "parkfleet.db") as db:
        stored = {row[0] for row in db.execute("SELECT id FROM tasks")}
    assert created <= stored


def test_demo_prints_a_working_curl_example(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "fleet.cli", "demo", "--robots", "2", "--port", "0"]
    cmd += ["--zenoh-listen", "tcp/127.0.0.1:0", "--data-dir", str(tmp_path / "demo")]
    cmd += ["--time-scale", SIM_TIME_SCALE, "--spawn", "grid"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.pop("PARKFLEET_API_TOKEN", None)
    with (tmp_path / "demo.err").open("w") as err:
        demo = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=err, text=True, env=env
        )
    try:
        assert demo.stdout is not None
        lines: list[str] = []
        for line in demo.stdout:
            lines.append(line)
            if "Ctrl-C stops the demo" in line:
                break
        text = "".join(lines)
        drain = threading.Thread(target=demo.stdout.read, daemon=True)  # keep draining
        drain.start()
        url = re.search(r"API on (http://\S+)", text)
        curl = re.search(r"curl -s -X POST (\S+)/tasks .* -d '(.*)'", text)
        assert url and curl, text
        assert curl[1] == url[1]
        with httpx.Client(base_url=url[1], timeout=10) as client:
            wait_robots(client, 2)
            created = client.post("/tasks", json=json.loads(curl[2]))
            assert created.status_code == 201, created.text
            wait_status(client, created.json()["id"], "succeeded")
        demo.send_signal(signal.SIGINT)
        assert demo.wait(20) == 0
        drain.join(5)
    finally:
        terminate(demo)
        if demo.stdout is not None:
            demo.stdout.close()
