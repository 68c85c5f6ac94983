"""``parkfleet bench zenoh``: N robots' state streams at the agents' real rates, into the
fleet service and into the robots themselves.

For each N (10, 100, 1000 by default) a ``parkfleet sim --robots N --rate R`` process
(full robot agents, 50 Hz by default like ``control_rate_hz``: idle robots still tick,
publish their peer stream every tick on their cell's key, their fleet-rate stream at
``fleet_rate_hz`` and subscribe to the cells around them) connects to a Zenoh router in
this process, on which the real :class:`~fleet.service.fleet_service.FleetService` listens
through the real :class:`~fleet.service.zenoh_bus.ZenohFleetBus`, as in ``parkfleet
serve`` (SQLite store in a temporary directory, tick thread running). The robots stand at
seeded random spots, one per ``--area`` m² (default 10), bodies apart
(:func:`spread_spawn`). Every state the bus decodes is timed on its way into
``FleetService.on_state``. Over a window, after a warm-up:

* ``delivered_per_s`` / ``delivered_ratio`` -- states that reached ``on_state`` a second,
  and their share of N x the fleet rate (the service reads the fleet-rate stream);
* ``age_p50_ms`` / ``age_p99_ms`` -- age of each state as it reaches ``on_state`` (wall
  time - the robot's stamp: encode, publish, router, decode, waiting for the callback);
* ``on_state_p50_us`` / ``on_state_p99_us`` -- time inside ``on_state`` (its lock included);
* ``cpu_ms_per_1000_states`` -- CPU of this process (router + bus + service) per 1000
  delivered states; ``cpu_service`` and ``cpu_robots`` -- CPU time / wall time (1.0 = one
  core) of this process and of the robots' process;
* ``dropped`` -- states the service side dropped (bus decoder, callback errors);
  ``robots_overran`` -- the robots' own ticks that overran (their rate not kept);
* ``probes`` -- what robots receive: :mod:`fleet.bench.peer_probe` (its own process and
  sessions) subscribes as the agents of the :data:`PROBES` most crowded robots do, and
  reports each one's peer states a second, peers heard (``peers_max``), the age of those
  states and any peer within the peer radius never heard (``missed``).

``--profile FILE`` records this process with py-spy (if installed) for the largest N
(``.svg`` flame graph, ``.json`` speedscope, ``.txt`` collapsed stacks).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Literal

import numpy as np

from fleet.bench.metrics import percentile
from fleet.bench.procstat import cpu_seconds
from fleet.core.wire import (
    CancelAssignment,
    ControlCommand,
    ObstacleSet,
    ParkAssignment,
    RobotDescription,
    RobotState,
)
from fleet.io.processes import parkfleet_command, terminate
from fleet.io.settings import load_settings
from fleet.io.transport import tcp_endpoint
from fleet.service.bus import FleetBus, FleetSink
from fleet.service.host import open_fleet

Source = Literal["agents", "stream"]

DEFAULT_SIZES = (10, 100, 1000)
RATE_HZ = 50.0
TARGET_DELIVERED = 0.99
TARGET_AGE_P99_MS = 50.0
TARGET_CPU_SERVICE = 0.5  # cores
TARGET_PEERS = 25  # peers a robot hears at one robot per 10 m^2
AREA_PER_ROBOT_M2 = 10.0
PROBES = 4
MIN_SPACING_M = 0.5  # centres apart: two bodies of 0.2 m and a little air


def spread_spawn(
    robots: int, area_per_robot_m2: float = AREA_PER_ROBOT_M2, seed: int = 0
) -> list[dict[str, float | str]]:
    """Seeded uniform spots (``b1`` ... ``bN``) in a square of N x ``area_per_robot_m2``
    [m²] centred on the origin, centres at least :data:`MIN_SPACING_M` apart."""
    rng = np.random.default_rng(seed)
    half = math.sqrt(robots * area_per_robot_m2) / 2
    placed = np.empty((0, 2))
    while len(placed) < robots:
        p = rng.uniform(-half, half, size=2)
        if not len(placed) or np.min(np.hypot(*(placed - p).T)) >= MIN_SPACING_M:
            placed = np.vstack([placed, p])
    return [{"id": f"b{i + 1}", "x": float(x), "y": float(y)} for i, (x, y) in enumerate(placed)]


def crowded(spawn: list[dict[str, float | str]], radius: float, count: int) -> list[str]:
    """The ``count`` robots with the most others within ``radius`` [m] (the hardest spots
    for the no-miss claim), ties by id."""
    xy = np.array([(float(e["x"]), float(e["y"])) for e in spawn])
    near = (np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1)) <= radius).sum(1)
    order = sorted(range(len(spawn)), key=lambda i: (-int(near[i]), i))
    return [str(spawn[i]["id"]) for i in order[:count]]


class _Timing:
    """What reached ``on_state`` while recording: arrival ages and time spent inside."""

    def __init__(self) -> None:
        self.recording = False
        self.ages: list[float] = []  # list.append is atomic: callbacks need no lock
        self.inside: list[float] = []
        self.robots: set[str] = set()


class _TimedSink:
    """The service as the bus's sink, every ``on_state`` timed."""

    def __init__(self, sink: FleetSink, timing: _Timing) -> None:
        self._sink = sink
        self._timing = timing

    def on_state(self, state: RobotState) -> None:
        arrived = time.time()
        t0 = time.perf_counter()
        self._sink.on_state(state)
        inside = time.perf_counter() - t0
        timing = self._timing
        timing.robots.add(state.robot_id)
        if timing.recording:
            timing.ages.append(arrived - state.stamp)
            timing.inside.append(inside)

    def on_robot_alive(self, robot_id: str) -> None:
        self._sink.on_robot_alive(robot_id)

    def on_robot_gone(self, robot_id: str) -> None:
        self._sink.on_robot_gone(robot_id)

    def on_description(self, description: RobotDescription) -> None:
        self._sink.on_description(description)

    def on_control(self, command: ControlCommand) -> None:
        self._sink.on_control(command)

    def obstacles(self) -> list[Any]:
        return self._sink.obstacles()

    def last_states(self) -> list[tuple[RobotState, float]]:
        return self._sink.last_states()


class _TimedBus:
    """The real Zenoh bus, delivering to a timed sink (``FleetBus``)."""

    def __init__(self, bus: FleetBus, timing: _Timing) -> None:
        self._bus = bus
        self._timing = timing

    def start(self, sink: FleetSink) -> None:
        self._bus.start(_TimedSink(sink, self._timing))

    def publish_assignment(self, msg: ParkAssignment | CancelAssignment) -> None:
        self._bus.publish_assignment(msg)

    def publish_obstacles(self, msg: ObstacleSet) -> None:
        self._bus.publish_obstacles(msg)

    def publish_control(self, msg: ControlCommand) -> None:
        self._bus.publish_control(msg)

    @property
    def counters(self) -> dict[str, int]:
        return self._bus.counters

    def close(self) -> None:
        self._bus.close()


def _dropped(counters: dict[str, int]) -> int:
    return sum(n for k, n in counters.items() if "dropped" in k or "errors" in k)


@contextmanager
def _robots(
    endpoint: str, fleet: str, spawn: Path, rate: float, log: Path, source: Source
) -> Iterator[subprocess.Popen[bytes]]:
    """The robots' process (stderr to ``log``): ``parkfleet sim`` (``agents``) or the light
    :mod:`fleet.bench.state_stream` (``stream``); stopped and reaped on exit."""
    robots = len(json.loads(spawn.read_text()))
    if source == "agents":
        cmd = parkfleet_command(
            "sim", "--robots", str(robots), "--rate", str(rate), "--connect", endpoint,
            "--spawn", str(spawn),
        )  # fmt: skip
    else:
        cmd = [sys.executable, "-m", "fleet.bench.state_stream", "--connect", endpoint,
               "--spawn", str(spawn), "--rate", str(rate)]  # fmt: skip
    env = os.environ | {"PARKFLEET_FLEET_NAME": fleet, "PYTHONUNBUFFERED": "1"}
    with log.open("wb") as err:
        proc = subprocess.Popen(
            cmd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=err
        )
    try:
        assert proc.stdout is not None
        proc.stdout.readline()  # the ready line, once every robot is declared
        yield proc
    finally:
        terminate(proc, timeout=30)
        if proc.stdout is not None:
            proc.stdout.close()


@contextmanager
def _probes(
    endpoint: str, fleet: str, spawn: Path, robot_ids: list[str]
) -> Iterator[subprocess.Popen[str]]:
    """The :mod:`fleet.bench.peer_probe` process, subscribed (its ready line read)."""
    cmd = [sys.executable, "-m", "fleet.bench.peer_probe", "--connect", endpoint,
           "--spawn", str(spawn)] + [a for rid in robot_ids for a in ("--robot", rid)]  # fmt: skip
    env = os.environ | {"PARKFLEET_FLEET_NAME": fleet, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        proc.stdout.readline()  # ready
        yield proc
    finally:
        terminate(proc, timeout=30)
        for stream in (proc.stdin, proc.stdout):
            if stream is not None:
                stream.close()


def _tell(proc: subprocess.Popen[str], line: str) -> None:
    assert proc.stdin is not None
    proc.stdin.write(line + "\n")
    proc.stdin.flush()


def _probe_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The probes' worst case (most states, most peers, oldest) and every miss."""
    if not rows:
        return {}
    return {
        "peer_states_per_s_max": max(r["peer_states_per_s"] for r in rows),
        "peer_states_per_s_mean": sum(r["peer_states_per_s"] for r in rows) / len(rows),
        "peers_max": max(r["peers_heard"] for r in rows),
        "peers_within_radius": sum(r["peers_within_radius"] for r in rows),
        "missed": sum(len(r["missed_within_radius"]) for r in rows),
        "peer_age_p50_ms": max(r["age_p50_ms"] for r in rows),
        "peer_age_p99_ms": max(r["age_p99_ms"] for r in rows),
    }


@contextmanager
def _py_spy(path: Path | None) -> Iterator[None]:
    """py-spy recording this process (native frames too) while the block runs."""
    exe = shutil.which("py-spy") or str(Path(sys.executable).with_name("py-spy"))
    if path is None or not Path(exe).exists():
        yield
        return
    recorder = subprocess.Popen(
        [exe, "record", "--pid", str(os.getpid()), "--output", str(path), "--format",
         {".json": "speedscope", ".txt": "raw"}.get(path.suffix, "flamegraph"), "--rate", "200",
         "--threads", "--idle", "--nonblocking"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        yield
    finally:
        recorder.send_signal(signal.SIGINT)
        try:
            recorder.wait(60)
        except subprocess.TimeoutExpired:
            recorder.kill()
            recorder.wait()


def measure(
    robots: int,
    rate: float = RATE_HZ,
    warmup: float = 3.0,
    window: float = 10.0,
    fleet: str = "bench",
    profile: Path | None = None,
    source: Source = "agents",
    area: float = AREA_PER_ROBOT_M2,
) -> dict[str, Any]:
    """One row: ``robots`` robots at ``rate`` Hz into a live fleet service."""
    timing = _Timing()
    with tempfile.TemporaryDirectory(prefix="parkfleet-bench-") as tmp:
        router_settings = load_settings(
            listen=["tcp/127.0.0.1:0"], fleet_name=fleet, data_dir=Path(tmp)
        )
        fleet_rate = min(rate, router_settings.fleet_rate_hz)
        layout = spread_spawn(robots, area)
        probe_ids = crowded(layout, router_settings.avoidance.peer_radius, min(PROBES, robots))
        with open_fleet(router_settings, wrap_bus=lambda bus: _TimedBus(bus, timing)) as running:
            service = running.service
            endpoint = tcp_endpoint(running.locators)
            log = Path(tmp) / "sim.log"
            spawn = Path(tmp) / "spawn.json"
            spawn.write_text(json.dumps(layout))
            with (
                _robots(endpoint, fleet, spawn, rate, log, source) as proc,
                _probes(endpoint, fleet, spawn, probe_ids) as probe,
            ):
                deadline = time.monotonic() + 60
                while len(timing.robots) < robots and time.monotonic() < deadline:
                    time.sleep(0.1)
                time.sleep(warmup)
                counters0 = service.counters
                wall0, cpu0, child0 = time.monotonic(), time.process_time(), cpu_seconds(proc.pid)
                timing.recording = True
                _tell(probe, "go")
                with _py_spy(profile):
                    time.sleep(window)
                timing.recording = False
                _tell(probe, "stop")
                wall = time.monotonic() - wall0
                cpu = time.process_time() - cpu0
                child_cpu = cpu_seconds(proc.pid) - child0
                counters1 = service.counters
                assert probe.stdout is not None
                probes = json.loads(probe.stdout.readline())["probes"]
            overran = _overruns(log.read_text(errors="replace"))
    delivered = len(timing.ages)
    ages_ms = [1e3 * a for a in timing.ages]
    inside_us = [1e6 * d for d in timing.inside]
    return {
        "robots": robots,
        "source": source,
        "rate_hz": rate,
        "fleet_rate_hz": fleet_rate,
        "area_per_robot_m2": area,
        "delivered_per_s": delivered / wall,
        "expected_per_s": robots * fleet_rate,
        "delivered_ratio": delivered / wall / (robots * fleet_rate),
        "age_p50_ms": percentile(ages_ms, 50),
        "age_p99_ms": percentile(ages_ms, 99),
        "age_max_ms": percentile(ages_ms, 100),
        "on_state_p50_us": percentile(inside_us, 50),
        "on_state_p99_us": percentile(inside_us, 99),
        "robots_seen": len(timing.robots),
        "cpu_service": cpu / wall,
        "cpu_robots": child_cpu / wall,
        "cpu_ms_per_1000_states": 1e6 * cpu / delivered if delivered else float("nan"),
        "dropped": _dropped(counters1) - _dropped(counters0),
        "robots_overran": overran,
        "window_s": wall,
        **_probe_summary(probes),
        "probes": probes,
    }


def _overruns(stderr: str) -> str:
    """The robots' own report of overrun ticks (``sim: K of M steps overran``), if any."""
    lines = [line for line in stderr.splitlines() if "overran" in line]
    return lines[-1].split("sim: ", 1)[-1] if lines else "none"


def run(
    sizes: list[int],
    warmup: float,
    window: float,
    rate: float = RATE_HZ,
    as_json: bool = False,
    profile: Path | None = None,
    source: Source = "agents",
    area: float = AREA_PER_ROBOT_M2,
) -> int:
    """Measure each robot count in ``sizes`` and print the rows (table or JSON)."""
    rows = []
    for i, n in enumerate(sizes):
        largest = profile if n == max(sizes) else None
        row = measure(n, rate, warmup, window, f"bench{i}", largest, source, area)
        rows.append(row)
        if not as_json:
            print(
                f"{n:>5} robots ({source}) @ {rate:g} Hz, fleet rate {row['fleet_rate_hz']:g} Hz: "
                f"service got {row['delivered_per_s']:7.0f}/s "
                f"({100 * row['delivered_ratio']:.1f} % of {row['expected_per_s']:.0f}), "
                f"age p50 {row['age_p50_ms']:.1f} ms p99 {row['age_p99_ms']:.1f} ms, "
                f"on_state p99 {row['on_state_p99_us']:.0f} us, "
                f"CPU {row['cpu_ms_per_1000_states']:.0f} ms/1000 states "
                f"(service {row['cpu_service']:.2f}, robots {row['cpu_robots']:.2f} cores), "
                f"dropped {row['dropped']}, robot overruns: {row['robots_overran']}",
                flush=True,
            )
            if row["probes"]:
                print(
                    f"      each robot (worst of {len(row['probes'])} most crowded, one per "
                    f"{area:g} m²): {row['peer_states_per_s_max']:.0f} peer states/s from "
                    f"<= {row['peers_max']} peers, age p50 {row['peer_age_p50_ms']:.1f} ms "
                    f"p99 {row['peer_age_p99_ms']:.1f} ms; within the peer radius "
                    f"{row['peers_within_radius']}, missed {row['missed']}",
                    flush=True,
                )
    if as_json:
        print(json.dumps({"rows": rows}))
        return 0
    target = next((r for r in rows if r["robots"] == 1000), None)
    if target is not None:
        ok = (
            target["delivered_ratio"] >= TARGET_DELIVERED
            and target["age_p99_ms"] < TARGET_AGE_P99_MS
            and target["cpu_service"] <= TARGET_CPU_SERVICE
            and target["dropped"] == 0
        )
        print(
            f"target 1000 robots @ {rate:g} Hz: service gets its fleet-rate stream >= "
            f"{100 * TARGET_DELIVERED:.0f} % "
            f"(ratio {target['delivered_ratio'] / TARGET_DELIVERED:.2f}), "
            f"p99 age < {TARGET_AGE_P99_MS:.0f} ms (ratio "
            f"{target['age_p99_ms'] / TARGET_AGE_P99_MS:.2f}), <= {TARGET_CPU_SERVICE} core "
            f"(ratio {target['cpu_service'] / TARGET_CPU_SERVICE:.2f}), nothing dropped: "
            f"{'met' if ok else 'NOT met'}"
        )
    for row in rows:
        if row["probes"]:
            ok = row["peers_max"] <= TARGET_PEERS and row["missed"] == 0
            print(
                f"target {row['robots']} robots, one per {area:g} m²: each hears <= "
                f"{TARGET_PEERS} peers (worst {row['peers_max']}), none within the peer radius "
                f"missed ({row['missed']}): {'met' if ok else 'NOT met'}"
            )
    return 0
