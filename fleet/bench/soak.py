"""``parkfleet bench soak --minutes M``: does the server stay flat, and lose nothing, for M minutes?

A ``parkfleet serve`` child (temporary data directory) and ``robots`` simulated robots, time-
scaled, in ``groups`` ``parkfleet sim`` children, while this process keeps up, concurrently:

* a random stream of tasks (``POST /tasks``, random goals; a goal refused with 409 is not
  accepted and not counted), and cancels of random accepted tasks;
* event-stream clients (``GET /events``) connecting, reading a while, and leaving;
* readers of the task list (newest pages) and of finished tasks' plots;
* chaos: a robot group SIGKILLed now and then, and restarted a little later.

Every ``sample_s`` seconds the server's resident memory (RSS), open file descriptors,
threads and SQLite size (database + WAL) are sampled. At the end the stream stops, the
tasks still open are cancelled, the server is stopped, and the store is checked: every
accepted task is there, in a final state, and its history holds exactly one final
transition (``task_history``). Printed: the samples, the least-squares slope of RSS [MB/min]
and fds [1/min] with its standard error (the noise), and the check. The slopes leave out
the first fifth of the run (warm-up: imports, compiled code, caches filling). Target: slopes
within their noise (two standard errors) over 30 minutes, nothing lost.
"""

from __future__ import annotations

import asyncio
import json
import math
import random
import signal
import sqlite3
import subprocess
import tempfile
import time
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from fleet.bench.procstat import holdings
from fleet.core.tasks import TaskStatus
from fleet.io.processes import ServerProcess, running_server, sim_command, terminate
from fleet.io.settings import DB_FILE

YARD = (-10.0, 10.0, -10.0, 10.0)
FINAL = tuple(s.value for s in TaskStatus if s.final)
#: A request unanswered this long [s] is counted as a timeout (``Tally.timeouts``).
REQUEST_TIMEOUT_S = 30.0


@dataclass
class Sample:
    """The server at one moment of the soak."""

    minute: float
    rss_mb: float
    open_fds: int
    threads: int
    sqlite_mb: float
    accepted: int
    events_clients: int


@dataclass
class Slope:
    """Least-squares slope of a series over time [unit/min], its standard error, and the
    residual noise (standard deviation about the line)."""

    per_min: float
    stderr: float
    noise: float

    @property
    def flat(self) -> bool:
        """Within two standard errors of zero."""
        return abs(self.per_min) <= 2 * self.stderr or self.per_min <= 0


def slope(t: list[float], y: list[float]) -> Slope:
    """Fit ``y = a + b t``; ``b`` with its standard error (NaN with fewer than 3 points)."""
    if len(t) < 3:
        return Slope(math.nan, math.nan, math.nan)
    ts, ys = np.asarray(t, dtype=np.float64), np.asarray(y, dtype=np.float64)
    b, a = np.polyfit(ts, ys, 1)
    residuals = ys - (a + b * ts)
    noise = float(np.sqrt(np.sum(residuals**2) / (len(ts) - 2)))
    spread = float(np.sum((ts - ts.mean()) ** 2))
    return Slope(float(b), noise / math.sqrt(spread) if spread > 0 else math.nan, noise)


@dataclass
class Tally:
    """What the clients did and saw."""

    accepted: list[str] = field(default_factory=list)
    refused: int = 0  # 409: goal rejected (not accepted, not stored)
    cancelled: int = 0
    cancel_conflicts: int = 0  # 409: already final
    events_sessions: int = 0
    events_refused: int = 0  # 503: every slot taken
    event_frames: int = 0
    pages: int = 0
    plots: int = 0
    plots_limited: int = 0  # 429
    kills: int = 0
    server_errors: int = 0  # any 5xx
    unexpected: dict[str, int] = field(default_factory=dict)
    timeouts: dict[str, int] = field(default_factory=dict)  # no answer in REQUEST_TIMEOUT_S

    def saw(self, response: httpx.Response, *expected: int) -> None:
        if response.status_code >= 500:
            self.server_errors += 1
        if response.status_code not in expected:
            key = f"{response.request.method} {response.status_code}"
            self.unexpected[key] = self.unexpected.get(key, 0) + 1

    def timed_out(self, method: str, route: str) -> None:
        key = f"{method} {route}"
        self.timeouts[key] = self.timeouts.get(key, 0) + 1


async def call(
    client: httpx.AsyncClient, tally: Tally, method: str, url: str, route: str, **kwargs: Any
) -> httpx.Response | None:
    """One request; None, counted in ``tally`` under ``route``, if the server gave no answer
    within the client's timeout: a soak reports a stalled server, it does not die of it."""
    try:
        return await client.request(method, url, **kwargs)
    except httpx.TimeoutException:
        tally.timed_out(method, route)
        return None


def spawn_files(folder: Path, robots: int, groups: int) -> list[Path]:
    """One spawn file per robot group: ``robots`` on a grid over the yard, ids ``g<k>-<i>``."""
    cols = math.ceil(math.sqrt(2 * robots))
    rows = math.ceil(robots / cols)
    dx = (YARD[1] - YARD[0]) / cols
    dy = (YARD[3] - YARD[2]) / rows
    places = [
        (YARD[0] + dx * (i % cols + 0.5), YARD[2] + dy * (i // cols + 0.5)) for i in range(robots)
    ]
    paths = []
    for g in range(groups):
        mine = places[g::groups]
        path = folder / f"group{g}.json"
        path.write_text(
            json.dumps(
                [{"id": f"g{g}-{i}", "x": x, "y": y, "theta": 0.0} for i, (x, y) in enumerate(mine)]
            )
        )
        paths.append(path)
    return paths


class Robots:
    """The robot groups: ``parkfleet sim`` children that can be killed and restarted."""

    def __init__(self, endpoint: str, spawns: list[Path], time_scale: float, rate: float) -> None:
        self._endpoint = endpoint
        self._spawns = spawns
        self._time_scale = time_scale
        self._rate = rate
        self.procs: list[subprocess.Popen[bytes] | None] = [None] * len(spawns)

    def start(self, group: int) -> None:
        count = len(json.loads(self._spawns[group].read_text()))
        cmd = sim_command(
            self._endpoint,
            count,
            time_scale=self._time_scale,
            spawn=str(self._spawns[group]),
            extra=["--rate", str(self._rate)],
        )
        log = self._spawns[group].with_suffix(".log").open("ab")
        with log:
            self.procs[group] = subprocess.Popen(
                cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=log
            )

    def kill(self, group: int) -> None:
        proc = self.procs[group]
        if proc is not None:
            proc.send_signal(signal.SIGKILL)
            proc.wait(30)
            self.procs[group] = None

    def stop(self) -> None:
        for proc in self.procs:
            if proc is not None:
                terminate(proc)


def sqlite_mb(data: Path) -> float:
    return sum(p.stat().st_size for p in data.glob(DB_FILE + "*")) / 2**20


class Soak:
    """The concurrent clients of one soak run."""

    def __init__(
        self, server: ServerProcess, data: Path, robots: Robots, seed: int, sample_s: float
    ) -> None:
        self.server = server
        self.data = data
        self.robots = robots
        self.rng = random.Random(seed)
        self.sample_s = sample_s
        self.tally = Tally()
        self.samples: list[Sample] = []
        self.events_open = 0
        self.t0 = time.monotonic()

    def minute(self) -> float:
        return (time.monotonic() - self.t0) / 60.0

    @staticmethod
    async def pause(seconds: float, until: float) -> None:
        """Sleep ``seconds``, but not past ``until`` (the run ends on time)."""
        await asyncio.sleep(max(0.0, min(seconds, until - time.monotonic())))

    async def tasks(self, client: httpx.AsyncClient, until: float, per_s: float) -> None:
        while time.monotonic() < until:
            goal = {
                "x": self.rng.uniform(YARD[0] + 0.5, YARD[1] - 0.5),
                "y": self.rng.uniform(YARD[2] + 0.5, YARD[3] - 0.5),
                "theta": self.rng.uniform(-math.pi, math.pi),
            }
            r = await call(client, self.tally, "POST", "/tasks", "/tasks", json={"goal": goal})
            if r is not None:
                self.tally.saw(r, 201, 409)
                if r.status_code == 201:
                    self.tally.accepted.append(r.json()["id"])
                elif r.status_code == 409:
                    self.tally.refused += 1
            await self.pause(self.rng.expovariate(per_s), until)

    async def cancels(self, client: httpx.AsyncClient, until: float, per_s: float) -> None:
        while time.monotonic() < until:
            await self.pause(self.rng.expovariate(per_s), until)
            if self.tally.accepted and time.monotonic() < until:
                task_id = self.rng.choice(self.tally.accepted[-200:])
                url = f"/tasks/{task_id}/cancel"
                r = await call(client, self.tally, "POST", url, "/tasks/{id}/cancel")
                if r is None:
                    continue
                self.tally.saw(r, 200, 409)
                self.tally.cancelled += r.status_code == 200
                self.tally.cancel_conflicts += r.status_code == 409

    async def event_client(self, until: float) -> None:
        """Connect, read for a random while, leave; again until the end."""
        async with httpx.AsyncClient(base_url=self.server.url, timeout=None) as client:
            while time.monotonic() < until:
                stay = time.monotonic() + self.rng.uniform(1.0, 20.0)
                try:
                    async with client.stream("GET", "/events") as response:
                        if response.status_code == 503:
                            self.tally.events_refused += 1
                        else:
                            self.tally.saw(response, 200)
                            self.tally.events_sessions += 1
                            self.events_open += 1
                            try:
                                async for line in response.aiter_lines():
                                    self.tally.event_frames += line.startswith("event:")
                                    if time.monotonic() > min(stay, until):
                                        break
                            finally:
                                self.events_open -= 1
                except httpx.HTTPError:
                    pass  # the server cut us off (too slow) or went away: connect again
                await self.pause(self.rng.uniform(0.5, 5.0), until)

    async def readers(self, client: httpx.AsyncClient, until: float) -> None:
        while time.monotonic() < until:
            await self.pause(self.rng.uniform(1.0, 4.0), until)
            r = await call(
                client,
                self.tally,
                "GET",
                "/tasks",
                "/tasks",
                params={"order": "newest", "limit": 50},
            )
            if r is None:
                continue
            self.tally.saw(r, 200)
            self.tally.pages += 1
            finished = [t["id"] for t in r.json() if t["status"] == "succeeded"]
            if finished:
                plot = await call(
                    client,
                    self.tally,
                    "GET",
                    f"/tasks/{self.rng.choice(finished)}/plot.png",
                    "plot.png",
                )
                if plot is None:
                    continue
                self.tally.saw(plot, 200, 409, 429)
                self.tally.plots += plot.status_code == 200
                self.tally.plots_limited += plot.status_code == 429

    async def chaos(self, until: float, every_s: float) -> None:
        while time.monotonic() < until:
            await self.pause(self.rng.uniform(0.5, 1.5) * every_s, until)
            if time.monotonic() >= until:
                return
            group = self.rng.randrange(len(self.robots.procs))
            await asyncio.to_thread(self.robots.kill, group)
            self.tally.kills += 1
            await self.pause(self.rng.uniform(2.0, 10.0), until)
            self.robots.start(group)

    async def sampler(self, until: float) -> None:
        while True:
            held = holdings(self.server.process.pid)
            sample = Sample(
                minute=self.minute(),
                rss_mb=held.rss_bytes / 2**20,
                open_fds=held.open_fds,
                threads=held.threads,
                sqlite_mb=sqlite_mb(self.data),
                accepted=len(self.tally.accepted),
                events_clients=self.events_open,
            )
            self.samples.append(sample)
            print(
                f"  {sample.minute:6.1f} min  RSS {sample.rss_mb:7.1f} MB  fds {sample.open_fds:4d}"
                f"  threads {sample.threads:3d}  SQLite {sample.sqlite_mb:6.2f} MB"
                f"  accepted {sample.accepted:6d}  event clients {sample.events_clients}",
                flush=True,
            )
            left = until - time.monotonic()
            if left <= 0.5:
                return
            await asyncio.sleep(min(self.sample_s, left))

    async def drain(self, client: httpx.AsyncClient) -> int:
        """Cancel every task still open (paging the list); how many were cancelled."""
        cancelled = 0
        for status in ("queued", "assigned", "driving"):
            while True:
                r = await client.get("/tasks", params={"status": status, "limit": 500})
                open_ids = [t["id"] for t in r.json()]
                if not open_ids:
                    break
                for task_id in open_ids:
                    c = await client.post(f"/tasks/{task_id}/cancel")
                    cancelled += c.status_code == 200
        return cancelled

    async def run(self, minutes: float, tasks_per_s: float, event_clients: int) -> int:
        until = self.t0 + 60.0 * minutes
        async with httpx.AsyncClient(base_url=self.server.url, timeout=REQUEST_TIMEOUT_S) as client:
            await asyncio.gather(
                self.sampler(until),
                self.tasks(client, until, tasks_per_s),
                self.cancels(client, until, tasks_per_s / 5),
                self.readers(client, until),
                self.chaos(until, every_s=45.0),
                *(self.event_client(until) for _ in range(event_clients)),
            )
            return await self.drain(client)


@dataclass
class Check:
    """The store after the soak, against what the server accepted."""

    accepted: int
    stored: int
    lost: int  # accepted, not in the store
    not_final: int
    final_transitions_not_one: int  # tasks whose history has 0 or 2+ final transitions
    by_status: dict[str, int]

    @property
    def ok(self) -> bool:
        return self.lost == 0 and self.not_final == 0 and self.final_transitions_not_one == 0


def check_store(db: Path, accepted: list[str]) -> Check:
    marks = ",".join("?" for _ in FINAL)
    with sqlite3.connect(db) as conn:
        status = dict(conn.execute("SELECT id, status FROM tasks").fetchall())
        finals = dict(
            conn.execute(
                f"SELECT task_id, COUNT(*) FROM task_history WHERE status IN ({marks})"
                " GROUP BY task_id",
                FINAL,
            ).fetchall()
        )
    conn.close()
    by_status: dict[str, int] = {}
    for task_id in accepted:
        s = status.get(task_id, "lost")
        by_status[s] = by_status.get(s, 0) + 1
    return Check(
        accepted=len(accepted),
        stored=len(status),
        lost=sum(t not in status for t in accepted),
        not_final=sum(t in status and status[t] not in FINAL for t in accepted),
        final_transitions_not_one=sum(finals.get(t, 0) != 1 for t in accepted),
        by_status=by_status,
    )


@dataclass
class SoakResult:
    minutes: float
    robots: int
    samples: list[Sample]
    rss: Slope
    fds: Slope
    tally: Tally
    drained: int
    check: Check

    def as_dict(self) -> dict[str, Any]:
        return asdict(self) | {"rss_flat": self.rss.flat, "fds_flat": self.fds.flat}


def soak(
    minutes: float,
    robots: int = 50,
    groups: int = 5,
    time_scale: float = 4.0,
    rate: float = 10.0,
    tasks_per_s: float = 2.0,
    event_clients: int = 4,
    sample_s: float = 60.0,
    seed: int = 1,
) -> SoakResult:
    """Run the soak (see the module docstring) and check the store."""
    env = {"PARKFLEET_YARD": json.dumps(YARD), "PARKFLEET_TASK_TIMEOUT_S": "60"}
    with ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="parkfleet-soak-")))
        data = tmp / "data"
        log = stack.enter_context((tmp / "serve.log").open("w"))
        server = stack.enter_context(running_server(data, env=env, stderr=log))
        group_robots = Robots(
            server.zenoh_endpoint, spawn_files(tmp, robots, groups), time_scale, rate
        )
        stack.callback(group_robots.stop)
        for group in range(groups):
            group_robots.start(group)
        run = Soak(server, data, group_robots, seed, sample_s)
        print(
            f"soak: {minutes:g} min, {robots} robots in {groups} groups (time scale "
            f"{time_scale:g}, {rate:g} Hz), ~{tasks_per_s:g} tasks/s, {event_clients} event "
            f"clients; server pid {server.process.pid}",
            flush=True,
        )
        drained = asyncio.run(run.run(minutes, tasks_per_s, event_clients))
        group_robots.stop()
        server.stop()
        check = check_store(data / DB_FILE, run.tally.accepted)
    # The first fifth is warm-up (imports, compiled code, caches filling): not in the slopes.
    steady = [s for s in run.samples if s.minute >= minutes / 5]
    t = [s.minute for s in steady]
    return SoakResult(
        minutes=minutes,
        robots=robots,
        samples=run.samples,
        rss=slope(t, [s.rss_mb for s in steady]),
        fds=slope(t, [float(s.open_fds) for s in steady]),
        tally=run.tally,
        drained=drained,
        check=check,
    )


def run(minutes: float, as_json: bool = False, **options: Any) -> int:
    """Print the soak's samples, slopes and check; exit code 1 if a task was lost."""
    if minutes <= 0:
        raise ValueError("--minutes must be positive")
    result = soak(minutes, **options)
    if as_json:
        print(json.dumps(result.as_dict()))
        return 0 if result.check.ok else 1
    t, c = result.tally, result.check
    print(
        f"RSS slope {result.rss.per_min:+.3f} ± {result.rss.stderr:.3f} MB/min "
        f"(noise {result.rss.noise:.2f} MB): {'flat' if result.rss.flat else 'GROWING'}"
    )
    print(
        f"fds slope {result.fds.per_min:+.3f} ± {result.fds.stderr:.3f} /min "
        f"(noise {result.fds.noise:.2f}): {'flat' if result.fds.flat else 'GROWING'}"
    )
    print(
        f"clients: {len(t.accepted)} tasks accepted, {t.refused} refused (409), "
        f"{t.cancelled} cancelled, {result.drained} open ones cancelled at the end; "
        f"{t.events_sessions} event sessions ({t.event_frames} frames, {t.events_refused} "
        f"refused), {t.pages} pages, {t.plots} plots ({t.plots_limited} rate-limited), "
        f"{t.kills} robot groups killed; server errors {t.server_errors}, "
        f"unexpected {t.unexpected}, timeouts {t.timeouts}"
    )
    print(
        f"store: {c.accepted} accepted, {c.stored} stored, {c.lost} lost, {c.not_final} not "
        f"final, {c.final_transitions_not_one} without exactly one final transition; "
        f"{c.by_status}: {'nothing lost' if c.ok else 'FAILED'}"
    )
    return 0 if c.ok else 1
