"""``parkfleet bench api``: POST /tasks throughput and latency against a live server.

A ``parkfleet serve`` child runs with its real SQLite store in a temporary directory and no
robots (tasks stay queued). ``concurrency`` clients post distinct goals 1.5 m apart (the
yard is widened to 200 m x 200 m so thousands fit) and time each request from send to the
201. Client and server share this machine, so the client's own Python
cost is part of the numbers.
"""

from __future__ import annotations

import asyncio
import json
import math
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
from pydantic import BaseModel, computed_field

from fleet.io.processes import running_server

YARD = (-100.0, 100.0, -100.0, 100.0)
SPACING_M = 1.5  # > the peer influence radius (1 m): goals that close are rejected
TARGET_RATE = 500.0
TARGET_P99_MS = 50.0


def goals(n: int, start: int = 0) -> list[dict[str, float]]:
    """``n`` goals on a grid ``SPACING_M`` apart inside ``YARD``."""
    side = int((YARD[1] - YARD[0]) / SPACING_M) - 1
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


class BenchResult(BaseModel):
    requests: int
    concurrency: int
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


def measure(requests: int = 3000, concurrency: int = 16, warmup: int = 200) -> BenchResult:
    """Start a server, warm it up, then time ``requests`` POSTs."""
    token = "bench-token"
    headers = {"Authorization": f"Bearer {token}"}
    env = {"PARKFLEET_YARD": json.dumps(YARD), "PARKFLEET_API_TOKEN": token}
    bodies = [{"goal": g} for g in goals(warmup + requests)]
    with (
        tempfile.TemporaryDirectory(prefix="parkfleet-bench-") as tmp,
        running_server(Path(tmp), env=env) as server,
    ):
        asyncio.run(post_all(server.url, bodies[:warmup], concurrency, headers))
        latencies, statuses, wall = asyncio.run(
            post_all(server.url, bodies[warmup:], concurrency, headers)
        )
    latencies.sort()
    q = statistics.quantiles(latencies, n=100, method="inclusive")
    created = statuses.get(201, 0)
    return BenchResult(
        requests=requests,
        concurrency=concurrency,
        created=created,
        statuses={str(k): v for k, v in sorted(statuses.items())},
        wall_s=wall,
        tasks_per_s=created / wall if wall > 0 else math.nan,
        p50_ms=1e3 * q[49],
        p99_ms=1e3 * q[98],
        max_ms=1e3 * latencies[-1],
    )


def run(requests: int = 3000, concurrency: int = 16, as_json: bool = False) -> int:
    if requests < 2 or concurrency < 1:
        raise ValueError("--requests must be at least 2 and --concurrency at least 1")
    r = measure(requests, concurrency)
    if as_json:
        print(r.model_dump_json())
        return 0
    print(f"POST /tasks, store on, {concurrency} concurrent clients, {requests} requests:")
    print(f"  created     {r.created} (statuses {r.statuses})")
    print(
        f"  throughput  {r.tasks_per_s:.0f} tasks/s  "
        f"(target >= {TARGET_RATE:.0f}: ratio {r.tasks_per_s / TARGET_RATE:.2f})"
    )
    print(
        f"  latency     p50 {r.p50_ms:.1f} ms   p99 {r.p99_ms:.1f} ms   max {r.max_ms:.1f} ms"
        f"  (target p99 < {TARGET_P99_MS:.0f} ms: ratio {r.p99_ms / TARGET_P99_MS:.2f})"
    )
    print(f"  target met: {'yes' if r.meets_target else 'no'}")
    return 0
