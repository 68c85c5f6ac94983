"""``parkfleet bench api``: POST /tasks throughput and latency against a live, loaded server.

A ``parkfleet serve`` child runs with its real SQLite store in a temporary directory, and
``robots`` simulated robots (``parkfleet sim``, default 50) stream their state to it at
``rate`` Hz (default 50, the agents' real rate) from a row along the yard's bottom edge:
the service's state path, the planner and the dispatch all run while the requests come in,
and robots drive off to park as tasks are assigned to them. ``concurrency`` clients post
distinct goals 1.5 m apart (the yard is widened to 200 m x 200 m so thousands fit) and time
each request from send to the 201.
Timing starts once the planner has made its first plans (after ``warmup`` untimed POSTs):
a cold cache of compiled code (a fresh checkout) is compiled there, not in the figures;
the plans made while timing are reported (a planner that never finished one would make
the server look faster than it is).
Client, server, its planner and the robots share this machine, so their CPU is part of the
numbers; the CPU of each (1.0 = one core) is reported. The clients are aiohttp's (one
connection each): ~0.25 ms of CPU a request here, where httpx's cost ~1.2 ms, CPU taken
from the server on a 2-core machine. ``--robots 0`` gives the idle-server figure.
``planners``: where the server plans -- ``process`` (the default, as ``parkfleet serve``'s:
``Settings.planner_process``, fleet/service/planner_process.py) or ``thread``; both: one
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

import aiohttp
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


class Posted(BaseModel):
    """What :func:`post_all` measured."""

    latencies: list[float]  # [s], one per request, in completion order
    statuses: dict[int, int]
    wall_s: float
    cpu_s: float  # of this process (the clients) while posting


async def post_all(
    url: str, bodies: list[dict[str, Any]], concurrency: int, headers: dict[str, str]
) -> Posted:
    """POST every body from ``concurrency`` clients (one keep-alive connection each, so
    they do not contend for one pool)."""
    latencies: list[float] = []
    statuses: dict[int, int] = {}
    todo = iter(bodies)

    async def worker(client: aiohttp.ClientSession) -> None:
        for body in todo:
            t0 = time.perf_counter()
            async with client.post("/tasks", json=body, headers=headers) as response:
                await response.read()
            latencies.append(time.perf_counter() - t0)
            statuses[response.status] = statuses.get(response.status, 0) + 1

    timeout = aiohttp.ClientTimeout(total=30.0)
    clients = [
        aiohttp.ClientSession(url, connector=aiohttp.TCPConnector(limit=1), timeout=timeout)
        for _ in range(concurrency)
    ]
    try:
        for client in clients:  # connect before the clock starts
            async with client.get("/healthz") as response:
                await response.read()
        cpu0, t0 = time.process_time(), time.perf_counter()
        await asyncio.gather(*(worker(client) for client in clients))
        wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    finally:
        for client in clients:
            await client.close()
    return Posted(latencies=latencies, statuses=statuses, wall_s=wall, cpu_s=cpu)


PLANNERS = ("thread", "process")


class BenchResult(BaseModel):
    planner: str = "process"  # where the server planned (PLANNERS)
    requests: int
    concurrency: int
    robots: int
    robot_rate_hz: float
    robots_busy_at_end: int
    cpu_server: float  # the server's process (its planner process is cpu_planner)
    cpu_planner: float = 0.0
    cpu_robots: float
    cpu_clients: float = 0.0
    plans: int = 0  # plans the server made while timing
    plan_p50_ms: float | None = None  # their latency (the server's window of recent plans)
    load_average: float = 0.0  # the machine's 1-minute load average at the end
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


#: Plans the server must have made before the clock starts (robots assigned, then planned
#: again under way: the first plans compile what a fresh checkout has not yet cached).
WARM_PLANS = 2


def _planner(url: str) -> dict[str, Any]:
    with httpx.Client(base_url=url, timeout=10.0) as client:
        stats: dict[str, Any] = client.get("/healthz").json()["planner"]
    return stats


def _wait_for_plans(url: str, plans: int, timeout: float = 600.0) -> None:
    """Until the server made ``plans`` plans (compiling a cold cache can take minutes)."""
    deadline = time.monotonic() + timeout
    while _planner(url)["plans"] < plans:
        if time.monotonic() > deadline:
            raise RuntimeError(f"the server made fewer than {plans} plans in {timeout:.0f} s")
        time.sleep(0.5)


def _planner_pid(server_pid: int) -> int | None:
    """The server's planner process (the spawned child that is not multiprocessing's
    resource tracker), if it plans in one."""
    for child in Path(f"/proc/{server_pid}/task/{server_pid}/children").read_text().split():
        if "resource_tracker" not in Path(f"/proc/{child}/cmdline").read_text():
            return int(child)
    return None


def measure(
    requests: int = 3000,
    concurrency: int = 16,
    warmup: int = 200,
    robots: int = ROBOTS,
    rate: float = RATE_HZ,
    planner: str = "process",
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
        if robots:
            _wait_for_plans(server.url, WARM_PLANS)
        planner_pid = _planner_pid(server.process.pid) if planner == "process" else None
        pids = [server.process.pid, planner_pid, robots_pid]
        cpu0 = [0.0 if pid is None else cpu_seconds(pid) for pid in pids]
        plans0 = _planner(server.url)["plans"]
        posted = asyncio.run(post_all(server.url, bodies[warmup:], concurrency, headers))
        wall = posted.wall_s
        cpu = [
            0.0 if pid is None else (cpu_seconds(pid) - c0) / wall
            for pid, c0 in zip(pids, cpu0, strict=True)
        ]
        after = _planner(server.url)
        with httpx.Client(base_url=server.url, timeout=10.0) as client:
            busy = sum(r["task_id"] is not None for r in client.get("/robots").json())
    latencies, statuses = sorted(posted.latencies), posted.statuses
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
        cpu_planner=cpu[1],
        cpu_robots=cpu[2],
        cpu_clients=posted.cpu_s / wall,
        plans=after["plans"] - plans0,
        plan_p50_ms=after["p50_ms"],
        load_average=os.getloadavg()[0],
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
    planners: Sequence[str] = ("process",),
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
        planner_cpu = f", its planner {r.cpu_planner:.2f}" if r.planner == "process" else ""
        print(
            f"  load        CPU server {r.cpu_server:.2f}{planner_cpu}, robots "
            f"{r.cpu_robots:.2f}, clients {r.cpu_clients:.2f} cores (of {os.cpu_count()}; "
            f"load average {r.load_average:.1f}); {r.robots_busy_at_end} of {robots} robots "
            "on a task at the end"
        )
        p50 = "-" if r.plan_p50_ms is None else f"{r.plan_p50_ms:.0f} ms"
        print(f"  planner     {r.plans} plans while timing (p50 {p50})")
        print(f"  target met: {'yes' if r.meets_target else 'no'}")
    if len(results) == 2:
        a, b = results
        print(
            f"{b.planner} / {a.planner}: throughput x{b.tasks_per_s / a.tasks_per_s:.2f}, "
            f"p99 x{b.p99_ms / a.p99_ms:.2f}"
        )
    return 0
