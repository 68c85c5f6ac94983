"""``parkfleet bench failover``: two fleet services on one PostgreSQL; kill the leader N times.

Set-up (all on this host): a throwaway PostgreSQL cluster (or ``--store URL``); a Zenoh
router in this process (it outlives the services, as a standalone ``parkfleet router``
would on a site: robots stay connected when a service dies); ``parkfleet sim --robots R``
(real time, 50 Hz agents) connected to it; two ``parkfleet serve --store <url>``, each a
router meshed to ours; this process's observer session sees every assignment (with its
fencing term) and every robot state.

A task stream (one task every ``--interval`` s, to free bays of a grid, each POST with its
own ``Idempotency-Key``, retried against the other service on 503 or a refused
connection) runs throughout. Each round: wait until a leader and a standby are up and the
leader has commanded under its term; then ``SIGKILL`` the leader (``--mode stop``:
``SIGSTOP`` it for lease + 1 s, then ``SIGCONT``: a stalled leader that wakes up deposed);
measure until an assignment of a higher term is seen; start a new standby in the killed one's
place. Reported:

* ``failover`` p50 / p99 / max [s]: from the kill to the first assignment (or cancel) of the
  new term seen on the wire (the new leader needs work to send: the stream's next task, or
  a recovered assignment not yet acknowledged);
* ``elected`` p50 / p99 [s]: from the kill to the successor's term committed (the database's
  ``now()`` against this host's wall clock: same host);
* ``lost``: tasks answered 201 that the store no longer has, plus those unfinished at the
  end after a drain (``--drain`` s);
* ``duplicated``: idempotency keys that yielded two task ids, plus tasks assigned to two
  robots;
* ``stale_sent``: assignments of a lower term seen on a robot's key after a higher one (what
  a deposed leader sent); ``obeyed_deposed``: robots whose state then showed a task and
  revision that only such a stale message carried (what fencing must keep at 0).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from fleet.core.wire import CancelAssignment, Keys, ParkAssignment, RobotState
from fleet.io.decoder import Decoder
from fleet.io.postgres_cluster import TempCluster
from fleet.io.processes import ServerProcess, running_server, sim_command, terminate
from fleet.io.settings import load_settings
from fleet.io.transport import listening_locators, open_session, tcp_endpoint
from fleet.service.store_postgres import connect

DEFAULT_ROBOTS = 20
DEFAULT_KILLS = 20
LEASE_S = 2.0


@dataclass
class Wire:
    """What the observer saw: terms per robot key, first sighting of each term."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    first_seen: dict[int, float] = field(default_factory=dict)  # term -> monotonic
    highest_to: dict[str, int] = field(default_factory=dict)  # robot -> highest term sent
    stale: dict[str, set[tuple[str, int]]] = field(default_factory=lambda: defaultdict(set))
    current: dict[str, set[tuple[str, int]]] = field(default_factory=lambda: defaultdict(set))
    robots_of: dict[str, set[str]] = field(default_factory=lambda: defaultdict(set))
    stale_sent: int = 0
    obeyed: set[str] = field(default_factory=set)
    decoder: Decoder = field(default_factory=lambda: Decoder("bench failover"))

    def on_assignment(self, sample: Any) -> None:
        msg = self.decoder.decode_assignment(sample.payload.to_bytes())
        if msg is None:
            return
        now = time.monotonic()
        with self.lock:
            self.first_seen.setdefault(msg.term, now)
            rid = msg.robot_id
            top = self.highest_to.get(rid, 0)
            if msg.term < top:
                self.stale_sent += 1
                if isinstance(msg, ParkAssignment):
                    self.stale[rid].add((msg.task_id, msg.revision))
                return
            self.highest_to[rid] = msg.term
            if isinstance(msg, ParkAssignment):
                self.current[rid].add((msg.task_id, msg.revision))
                self.robots_of[msg.task_id].add(rid)
            elif isinstance(msg, CancelAssignment):
                self.robots_of[msg.task_id].discard(rid)

    def on_state(self, sample: Any) -> None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None or state.task_id is None:
            return
        running = (state.task_id, state.revision)
        with self.lock:
            rid = state.robot_id
            if running in self.stale[rid] and running not in self.current[rid]:
                self.obeyed.add(rid)

    def term_after(self, term: int) -> float | None:
        with self.lock:
            times = [t for k, t in self.first_seen.items() if k > term]
        return min(times) if times else None


@dataclass
class Stream:
    """The task stream: submissions, retried across the two services."""

    urls: list[str]
    bays: list[tuple[float, float]]
    interval_s: float
    lock: threading.Lock = field(default_factory=threading.Lock)
    ids_of_key: dict[str, set[str]] = field(default_factory=lambda: defaultdict(set))
    refused: int = 0  # 503 answers (a standby, or no leader yet)
    retried: int = 0
    stop: threading.Event = field(default_factory=threading.Event)

    def _post(self, key: str, goal: tuple[float, float]) -> str | None:
        body = {"goal": {"x": goal[0], "y": goal[1], "theta": 0.0}}
        deadline = time.monotonic() + 30.0
        k = 0
        while time.monotonic() < deadline and not self.stop.is_set():
            with self.lock:
                url = self.urls[k % len(self.urls)]
            k += 1
            try:
                r = httpx.post(f"{url}/tasks", json=body, headers={"Idempotency-Key": key},
                               timeout=2.0)  # fmt: skip
            except httpx.HTTPError:
                self.retried += 1
                self.stop.wait(0.05)
                continue
            if r.status_code == 201:
                task_id = str(r.json()["id"])
                with self.lock:
                    self.ids_of_key[key].add(task_id)
                return task_id
            if r.status_code == 503:
                self.refused += 1
                leader = r.headers.get("X-Parkfleet-Leader")
                with self.lock:
                    if leader and leader in self.urls:  # try the named leader next
                        k = self.urls.index(leader)
                self.stop.wait(0.05)
                continue
            return None  # 409 (bay taken by a parked robot) etc.: next bay
        return None

    def run(self) -> None:
        n = 0
        while not self.stop.wait(self.interval_s):
            goal = self.bays[n % len(self.bays)]
            self._post(f"bench-{n}", goal)
            n += 1

    def replace(self, old: str, new: str) -> None:
        with self.lock:
            self.urls[self.urls.index(old)] = new


def _health(url: str) -> dict[str, Any] | None:
    try:
        return dict(httpx.get(f"{url}/healthz", timeout=2.0).json())
    except (httpx.HTTPError, ValueError):
        return None


def _wait(predicate: Any, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > end:
            raise TimeoutError(f"bench failover: timed out waiting for {what}")
        time.sleep(0.02)


def _bays(robots: int) -> list[tuple[float, float]]:
    """Goals (more than the robots) 1.5 m apart on a grid of the default yard, outside the
    square the spawn grid
    (``parkfleet sim --spawn grid``, 1.5 m apart round the origin) covers, in a shuffled
    but fixed order."""
    half = 1.5 * (np.ceil(np.sqrt(robots)) - 1) / 2 + 1.5
    points = [
        (float(x), float(y))
        for x in np.arange(-9.0, 9.01, 1.5)
        for y in np.arange(-9.0, 9.01, 1.5)
        if max(abs(x), abs(y)) > half
    ]
    order = np.random.default_rng(0).permutation(len(points))
    return [points[k] for k in order]


def run(
    robots: int = DEFAULT_ROBOTS,
    kills: int = DEFAULT_KILLS,
    *,
    mode: str = "kill",
    interval_s: float = 1.0,
    drain_s: float = 30.0,
    store: str | None = None,
    as_json: bool = False,
) -> int:
    """Run the benchmark (module docstring); prints a table or JSON; returns 0."""
    with ExitStack() as stack:
        if store is None:
            store = stack.enter_context(TempCluster()).dsn
        router = stack.enter_context(
            open_session(load_settings(listen=["tcp/127.0.0.1:0"]), "router")
        )
        endpoint = tcp_endpoint(listening_locators(router))
        keys = Keys()
        wire = Wire()
        subs = [
            router.declare_subscriber(f"{keys.root}/robot/*/assignment", wire.on_assignment),
            router.declare_subscriber(keys.all_states, wire.on_state),
        ]
        for sub in subs:
            stack.callback(sub.undeclare)
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="pf-failover-")))
        env = {
            "PARKFLEET_CONNECT": json.dumps([endpoint]),
            "PARKFLEET_LEADER_LEASE_S": str(LEASE_S),
            "PARKFLEET_REPLAN_PERIOD_S": "1.0",
        }
        sim = subprocess.Popen(
            sim_command(endpoint, robots, time_scale=1.0, spawn="grid"),
            stdout=subprocess.DEVNULL,
            stderr=(tmp / "sim.log").open("w"),
        )
        stack.callback(terminate, sim)
        serial = [0]

        def start_service() -> ServerProcess:
            serial[0] += 1
            log = stack.enter_context((tmp / f"serve{serial[0]}.log").open("w"))
            return stack.enter_context(
                running_server(tmp / f"data{serial[0]}", "--store", store, env=env, stderr=log)
            )

        services = [start_service(), start_service()]
        stream = Stream([s.url for s in services], _bays(robots), interval_s)
        feeder = threading.Thread(target=stream.run, name="bench-stream", daemon=True)
        feeder.start()
        stack.callback(feeder.join, 40.0)
        stack.callback(stream.stop.set)

        def roles() -> dict[str, str]:
            out = {}
            for s in services:
                h = _health(s.url)
                out[s.url] = "down" if h is None else str(h.get("role"))
                if h is not None and h.get("role") == "leader":
                    out["term"] = str(h["term"])
            return out

        failovers: list[float] = []
        elections: list[float] = []  # kill -> the successor's term committed [s, wall]
        started = time.monotonic()
        for _ in range(kills):
            _wait(lambda: sorted(v for k, v in roles().items() if k != "term")
                  == ["leader", "standby"], 120, "a leader and a standby")  # fmt: skip
            now_roles = roles()
            term = int(now_roles["term"])
            leader = next(s for s in services if now_roles[s.url] == "leader")
            _wait(lambda t=term: t in wire.first_seen, 120, f"term {term} commanding")
            t0, wall0 = time.monotonic(), time.time()
            if mode == "stop":
                leader.process.send_signal(signal.SIGSTOP)
            else:
                leader.process.kill()
            _wait(lambda t=term: wire.term_after(t) is not None, 120, "a new term commanding")
            seen = wire.term_after(term)
            assert seen is not None
            failovers.append(seen - t0)
            elections.append(_elected_at(store, term) - wall0)
            print(f"bench failover: kill {len(failovers)}/{kills}: term {term} -> new term "
                  f"commanding after {seen - t0:.3f} s ({time.monotonic() - started:.0f} s in)",
                  file=sys.stderr, flush=True)  # fmt: skip
            if mode == "stop":
                time.sleep(max(0.0, t0 + LEASE_S + 1.0 - time.monotonic()))
                leader.process.send_signal(signal.SIGCONT)  # wakes deposed: stays a standby
            else:
                leader.process.wait(timeout=30)
                fresh = start_service()
                stream.replace(leader.url, fresh.url)
                services[services.index(leader)] = fresh
        stream.stop.set()
        feeder.join(timeout=40.0)
        result = _tally(wire, stream, services, drain_s)
        result |= {
            "robots": robots,
            "kills": kills,
            "mode": mode,
            "failover_p50_s": float(np.percentile(failovers, 50)),
            "failover_p99_s": float(np.percentile(failovers, 99)),
            "failover_max_s": max(failovers),
            "elected_p50_s": float(np.percentile(elections, 50)),
            "elected_p99_s": float(np.percentile(elections, 99)),
            "load_1min": os.getloadavg()[0],
        }
    _print(result, as_json)
    return 0


def _elected_at(dsn: str, term: int) -> float:
    """When the term after ``term`` was committed [s since epoch, the database's clock]."""
    with connect(dsn) as db:
        row = db.execute(
            "SELECT since FROM parkfleet_leader WHERE id = 1 AND term > %s", (term,)
        ).fetchone()
    return float("nan") if row is None else float(row[0])


def _tally(
    wire: Wire, stream: Stream, services: list[ServerProcess], drain_s: float
) -> dict[str, Any]:
    """Lost, duplicated and deposed-obeyed counts after a drain (module docstring)."""
    leader = next(
        (s for s in services if (h := _health(s.url)) and h.get("role") == "leader"), None
    )
    accepted = {i for ids in stream.ids_of_key.values() for i in ids}
    unfinished: set[str] = set()
    missing: set[str] = set()
    left_as: dict[str, int] = defaultdict(int)
    if leader is not None:
        end = time.monotonic() + drain_s

        def open_tasks() -> set[str]:
            left = set()
            for task_id in accepted:
                r = httpx.get(f"{leader.url}/tasks/{task_id}", timeout=5.0)
                if r.status_code == 404:
                    missing.add(task_id)
                elif r.json()["status"] not in ("succeeded", "failed", "cancelled"):
                    left.add(task_id)
            return left

        unfinished = open_tasks()
        while unfinished and time.monotonic() < end:
            time.sleep(1.0)
            unfinished = open_tasks()
        for task_id in unfinished:
            got = httpx.get(f"{leader.url}/tasks/{task_id}", timeout=5.0).json()
            left_as[str(got["status"])] += 1
    with wire.lock:
        two_robots = sum(1 for rids in wire.robots_of.values() if len(rids) > 1)
        return {
            "tasks_accepted": len(accepted),
            "lost": len(missing),
            "unfinished_after_drain": len(unfinished),
            "unfinished_by_status": dict(left_as),
            "duplicated": sum(1 for ids in stream.ids_of_key.values() if len(ids) > 1) + two_robots,
            "stale_sent": wire.stale_sent,
            "obeyed_deposed": len(wire.obeyed),
            "refused_503": stream.refused,
            "retried": stream.retried,
            "decoder_drops": wire.decoder.dropped_total,
        }


def _print(result: dict[str, Any], as_json: bool) -> None:
    if as_json:
        print(json.dumps(result, indent=2))
        return
    print(f"bench failover: {result['robots']} robots, {result['kills']} leader "
          f"{'SIGKILLs' if result['mode'] == 'kill' else 'SIGSTOP/SIGCONTs'}, load "
          f"{result['load_1min']:.1f}")  # fmt: skip
    print(f"  elected (kill -> successor's term committed): p50 {result['elected_p50_s']:.3f} s"
          f"  p99 {result['elected_p99_s']:.3f} s")  # fmt: skip
    print(f"  failover (kill -> first assignment of the new term): p50 "
          f"{result['failover_p50_s']:.3f} s  p99 {result['failover_p99_s']:.3f} s  max "
          f"{result['failover_max_s']:.3f} s")  # fmt: skip
    for k in ("tasks_accepted", "lost", "unfinished_after_drain", "duplicated", "stale_sent",
              "obeyed_deposed", "refused_503", "retried"):  # fmt: skip
        print(f"  {k:<24} {result[k]}")
