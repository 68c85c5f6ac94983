"""``parkfleet bench api``: POST /tasks throughput and latency against a live, loaded server.

A ``parkfleet serve`` child runs with its real SQLite store in a temporary directory, and
``robots`` simulated robots (``parkfleet sim``, default 50) stream their state to it at
``rate`` Hz (default 50, the agents' real rate) from a row along the yard's bottom edge:
the service's state path, the planner and the dispatch all run while the requests come in,
and robots drive off to park as tasks are assigned to them. ``concurrency`` clients post
distinct goals 1.5 m apart (the yard is widened to 200 m x 200 m so thousands fit) and time
each request from send to the 201.
Client, server and robots share this machine, so their CPU is part of the numbers; the
CPU of each (1.0 = one core) is reported. ``--robots 0`` gives the idle-server figure.
``planners``: where the server plans -- ``thread`` or ``process`` (the default of
``parkfleet serve``: ``Settings.planner_process``, fleet/service/planner_process.py); both: one
server each, one after the other in the same run, so their figures compare.
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import statistics
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
from pydantic import BaseModel, computed_field

from fleet.bench.procstat import cpu_seconds
from fleet.io.processes import running_server, sim_command, terminate

YARD = (-100.0, 100.0, -100.0, 100.0)
SPACING_M = 1.5  # > the peer influence radius (1 m): goals that close are rejected
TARGET_RATE = 500.0
TARGET_P99_MS = 50.0
ROBOTS = 50
RATE_HZ = 50.0


GRID_SIDE = int((YARD[1] - YARD[0]) / SPACING_M) - 1
#: Goal rows left free along the bottom edge, where the robots wait.
FREE_ROWS = 2


def goals(n: int, start: int = 0) -> list[dict[str, float]]:
    """``n`` goals on a grid ``SPACING_M`` apart inside ``YARD``."""
    side = GRID_SIDE
    out = []
    for k in range(start, start + n):
        i, j = divmod(k, side)
        out.append({"x": YARD[0] + SPACING_M * (j + 1), "y": YARD[2] + SPACING_M * (i + 1)})
    return out


async def post_all(
    url: str, bodies: list[dict[str, Any]], concurrency: int, headers: dict[str, str]
) -> tuple[list[float], dict[int, int], float]:
    """POST every body from ``concurrency`` clients (one keep-alive connection each, so
    they do not contend for one pool); latencies [s], status counts, wall time [s]."""
    latencies: list[float] = []
    statuses: dict[int, int] = {}
    todo = iter(bodies)

    async def worker(client: httpx.AsyncClient) -> None:
        for body in todo:
            t0 = time.perf_counter()
            response = await client.post("/tasks", json=body, headers=headers)
            latencies.append(time.perf_counter() - t0)
            statuses[response.status_code] = statuses.get(response.status_code, 0) + 1

    clients = [httpx.AsyncClient(base_url=url, timeout=30.0) for _ in range(concurrency)]
    try:
        for client in clients:  # connect before the clock starts
            await client.get("/healthz")
        t0 = time.perf_counter()
        await asyncio.gather(*(worker(client) for client in clients))
        wall = time.perf_counter() - t0
    finally:
        for client in clients:
            await client.aclose()
    return latencies, statuses, wall


PLANNERS = ("thread", "process")


class BenchResult(BaseModel):
    planner: str = "thread"  # where the server planned (PLANNERS)
    requests: int
    concurrency: int
    robots: int
    robot_rate_hz: float
    robots_busy_at_end: int
    cpu_server: float
    cpu_robots: float
    created: int
    statuses: dict[str, int]
    wall_s: float
    tasks_per_s: float
    p50_ms: float
    p99_ms: float
    max_ms: float
    target_tasks_per_s: float = TARGET_RATE
    target_p99_ms: float = TARGET_P99_MS

    @computed_field  # type: ignore[prop-decorator]
    @property
    def meets_target(self) -> bool:
        return self.tasks_per_s >= self.target_tasks_per_s and self.p99_ms < self.target_p99_ms


def spawn_row(robots: int) -> list[dict[str, float | str]]:
    """The robots in a row along the yard's bottom edge, 3 m apart, below the goals (a
    parking lot's entrance): the first tasks are a few metres away, as in a real yard."""
    return [
        {"id": f"robot-{i + 1}", "x": YARD[0] + 1.5 + 3.0 * i, "y": YARD[2] + 0.5, "theta": 1.57}
        for i in range(robots)
    ]


@contextmanager
def _robots(
    endpoint: str, robots: int, rate: float, env: dict[str, str], spawn: Path
) -> Iterator[int | None]:
    """``robots`` simulated robots at ``rate`` Hz on the server's router; yields their pid."""
    if robots == 0:
        yield None
        return
    spawn.write_text(json.dumps(spawn_row(robots)))
    cmd = sim_command(endpoint, robots, spawn=str(spawn), extra=["--rate", str(rate)])
    proc = subprocess.Popen(
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env=os.environ | env,
    )
    try:
        assert proc.stdout is not None
        proc.stdout.readline()  # ready once every robot is declared
        yield proc.pid
    finally:
        terminate(proc)
        if proc.stdout is not None:
            proc.stdout.close()


def _wait_for_robots(url: str, robots: int, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    with httpx.Client(base_url=url, timeout=10.0) as client:
        while len(client.get("/robots").json()) < robots:
            if time.monotonic() > deadline:
                raise RuntimeError(f"only some of the {robots} robots reached the server")
            time.sleep(0.2)


def measure(
    requests: int = 3000,
    concurrency: int = 16,
    warmup: int = 200,
    robots: int = ROBOTS,
    rate: float = RATE_HZ,
    planner: str = "thread",
) -> BenchResult:
    """Start a server (planning on ``planner``) and its robots, warm up, then time
    ``requests`` POSTs."""
    if planner not in PLANNERS:
        raise ValueError(f"planner must be one of {', '.join(PLANNERS)}")
    token = "bench-token"
    headers = {"Authorization": f"Bearer {token}"}
    env = {
        "PARKFLEET_YARD": json.dumps(YARD),
        "PARKFLEET_API_TOKEN": token,
        "PARKFLEET_PLANNER_PROCESS": str(planner == "process").lower(),
    }
    if robots > (YARD[1] - YARD[0] - 3.0) / 3.0:
        raise ValueError(f"at most {int((YARD[1] - YARD[0] - 3.0) / 3.0)} robots fit the row")
    bodies = [{"goal": g} for g in goals(warmup + requests, start=FREE_ROWS * GRID_SIDE)]
    with (
        tempfile.TemporaryDirectory(prefix="parkfleet-bench-") as tmp,
        running_server(Path(tmp) / "data", env=env) as server,
        _robots(server.zenoh_endpoint, robots, rate, env, Path(tmp) / "spawn.json") as robots_pid,
    ):
        _wait_for_robots(server.url, robots)
        asyncio.run(post_all(server.url, bodies[:warmup], concurrency, headers))
        pids = [server.process.pid] + ([robots_pid] if robots_pid is not None else [])
        cpu0 = [cpu_seconds(pid) for pid in pids]
        latencies, statuses, wall = asyncio.run(
            post_all(server.url, bodies[warmup:], concurrency, headers)
        )
        cpu = [(cpu_seconds(pid) - c0) / wall for pid, c0 in zip(pids, cpu0, strict=True)]
        with httpx.Client(base_url=server.url, timeout=10.0) as client:
            busy = sum(r["task_id"] is not None for r in client.get("/robots").json())
    latencies.sort()
    q = statistics.quantiles(latencies, n=100, method="inclusive")
    created = statuses.get(201, 0)
    return BenchResult(
        planner=planner,
        requests=requests,
        concurrency=concurrency,
        robots=robots,
        robot_rate_hz=rate,
        robots_busy_at_end=busy,
        cpu_server=cpu[0],
        cpu_robots=cpu[1] if len(cpu) > 1 else 0.0,
        created=created,
        statuses={str(k): v for k, v in sorted(statuses.items())},
        wall_s=wall,
        tasks_per_s=created / wall if wall > 0 else math.nan,
        p50_ms=1e3 * q[49],
        p99_ms=1e3 * q[98],
        max_ms=1e3 * latencies[-1],
    )


def run(
    requests: int = 3000,
    concurrency: int = 16,
    as_json: bool = False,
    robots: int = ROBOTS,
    rate: float = RATE_HZ,
    planners: Sequence[str] = ("thread",),
) -> int:
    if requests < 2 or concurrency < 1 or robots < 0:
        raise ValueError(
            "--requests must be at least 2, --concurrency at least 1, --robots at least 0"
        )
    results = [
        measure(requests, concurrency, robots=robots, rate=rate, planner=p) for p in planners
    ]
    if as_json:
        if len(results) == 1:
            print(results[0].model_dump_json())
        else:
            print(json.dumps([r.model_dump(mode="json") for r in results]))
        return 0
    print(
        f"POST /tasks, store on, {concurrency} concurrent clients, {requests} requests, "
        f"{robots} robots streaming state at {rate:g} Hz:"
    )
    for r in results:
        print("planner in its own process:" if r.planner == "process" else "planner on a thread:")
        print(f"  created     {r.created} (statuses {r.statuses})")
        print(
            f"  throughput  {r.tasks_per_s:.0f} tasks/s  "
            f"(target >= {TARGET_RATE:.0f}: ratio {r.tasks_per_s / TARGET_RATE:.2f})"
        )
        print(
            f"  latency     p50 {r.p50_ms:.1f} ms   p99 {r.p99_ms:.1f} ms   max {r.max_ms:.1f} ms"
            f"  (target p99 < {TARGET_P99_MS:.0f} ms: ratio {r.p99_ms / TARGET_P99_MS:.2f})"
        )
        print(
            f"  load        CPU server {r.cpu_server:.2f}, robots {r.cpu_robots:.2f} cores; "
            f"{r.robots_busy_at_end} of {robots} robots on a task at the end"
        )
        print(f"  target met: {'yes' if r.meets_target else 'no'}")
    if len(results) == 2:
        a, b = results
        print(
            f"{b.planner} / {a.planner}: throughput x{b.tasks_per_s / a.tasks_per_s:.2f}, "
            f"p99 x{b.p99_ms / a.p99_ms:.2f}"
        )
    return 0
