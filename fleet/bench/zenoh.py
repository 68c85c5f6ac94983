"""``parkfleet bench zenoh``: N robots' states at the agents' real rate into the fleet service.

For each N (10, 100, 1000 by default) a ``parkfleet sim --robots N --rate R`` process
(full robot agents, 50 Hz by default like ``control_rate_hz``: idle robots still tick,
publish their state every tick and subscribe to every peer's state) connects to a Zenoh
router in this process, on which the real :class:`~fleet.service.fleet_service.FleetService`
listens through the real :class:`~fleet.service.zenoh_bus.ZenohFleetBus`, as in
``parkfleet serve`` (SQLite store in a temporary directory, tick thread running). Every
state the bus decodes is timed on its way into ``FleetService.on_state``. Over a window,
after a warm-up:

* ``delivered_per_s`` / ``delivered_ratio`` -- states that reached ``on_state`` a second,
  and their share of N x R;
* ``age_p50_ms`` / ``age_p99_ms`` -- age of each state as it reaches ``on_state`` (wall
  time - the robot's stamp: encode, publish, router, decode, waiting for the callback);
* ``on_state_p50_us`` / ``on_state_p99_us`` -- time inside ``on_state`` (its lock included);
* ``cpu_ms_per_1000_states`` -- CPU of this process (router + bus + service) per 1000
  delivered states; ``cpu_service`` and ``cpu_robots`` -- CPU time / wall time (1.0 = one
  core) of this process and of the robots' process;
* ``dropped`` -- states the service side dropped (bus decoder, callback errors);
  ``robots_overran`` -- the robots' own ticks that overran (their rate not kept).

``--profile FILE`` records this process with py-spy (if installed) for the largest N
(``.svg`` flame graph, ``.json`` speedscope, ``.txt`` collapsed stacks).
"""

from __future__ import annotations

import json
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

from fleet.bench.procstat import cpu_seconds, percentile
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
TARGET_DELIVERED = 0.95
TARGET_AGE_P99_MS = 50.0


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
    endpoint: str, fleet: str, robots: int, rate: float, log: Path, source: Source
) -> Iterator[subprocess.Popen[bytes]]:
    """The robots' process (stderr to ``log``): ``parkfleet sim`` (``agents``) or the light
    :mod:`fleet.bench.state_stream` (``stream``); stopped and reaped on exit."""
    if source == "agents":
        cmd = parkfleet_command(
            "sim", "--robots", str(robots), "--rate", str(rate), "--connect", endpoint,
            "--spawn", "grid", "--id-prefix", "b",
        )  # fmt: skip
    else:
        cmd = [sys.executable, "-m", "fleet.bench.state_stream", "--connect", endpoint,
               "--robots", str(robots), "--rate", str(rate), "--prefix", "b"]  # fmt: skip
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
) -> dict[str, Any]:
    """One row: ``robots`` robots at ``rate`` Hz into a live fleet service."""
    timing = _Timing()
    with tempfile.TemporaryDirectory(prefix="parkfleet-bench-") as tmp:
        router_settings = load_settings(
            listen=["tcp/127.0.0.1:0"], fleet_name=fleet, data_dir=Path(tmp)
        )
        with open_fleet(router_settings, wrap_bus=lambda bus: _TimedBus(bus, timing)) as running:
            service = running.service
            endpoint = tcp_endpoint(running.locators)
            log = Path(tmp) / "sim.log"
            with _robots(endpoint, fleet, robots, rate, log, source) as proc:
                deadline = time.monotonic() + 60
                while len(timing.robots) < robots and time.monotonic() < deadline:
                    time.sleep(0.1)
                time.sleep(warmup)
                counters0 = service.counters
                wall0, cpu0, child0 = time.monotonic(), time.process_time(), cpu_seconds(proc.pid)
                timing.recording = True
                with _py_spy(profile):
                    time.sleep(window)
                timing.recording = False
                wall = time.monotonic() - wall0
                cpu = time.process_time() - cpu0
                child_cpu = cpu_seconds(proc.pid) - child0
                counters1 = service.counters
            overran = _overruns(log.read_text(errors="replace"))
    delivered = len(timing.ages)
    ages_ms = [1e3 * a for a in timing.ages]
    inside_us = [1e6 * d for d in timing.inside]
    return {
        "robots": robots,
        "source": source,
        "rate_hz": rate,
        "delivered_per_s": delivered / wall,
        "expected_per_s": robots * rate,
        "delivered_ratio": delivered / wall / (robots * rate),
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
) -> int:
    """Measure each robot count in ``sizes`` and print the rows (table or JSON)."""
    rows = []
    for i, n in enumerate(sizes):
        largest = profile if n == max(sizes) else None
        row = measure(n, rate, warmup, window, f"bench{i}", largest, source)
        rows.append(row)
        if not as_json:
            print(
                f"{n:>5} robots ({source}) @ {rate:g} Hz: "
                f"delivered {row['delivered_per_s']:7.0f}/s "
                f"({100 * row['delivered_ratio']:.1f} % of {row['expected_per_s']:.0f}), "
                f"age p50 {row['age_p50_ms']:.1f} ms p99 {row['age_p99_ms']:.1f} ms, "
                f"on_state p99 {row['on_state_p99_us']:.0f} us, "
                f"CPU {row['cpu_ms_per_1000_states']:.0f} ms/1000 states "
                f"(service {row['cpu_service']:.2f}, robots {row['cpu_robots']:.2f} cores), "
                f"dropped {row['dropped']}, robot overruns: {row['robots_overran']}",
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
            and target["dropped"] == 0
        )
        print(
            f"target 1000 robots @ {rate:g} Hz: delivered >= {100 * TARGET_DELIVERED:.0f} % "
            f"(ratio {target['delivered_ratio'] / TARGET_DELIVERED:.2f}), p99 age < "
            f"{TARGET_AGE_P99_MS:.0f} ms (ratio {target['age_p99_ms'] / TARGET_AGE_P99_MS:.2f}),"
            f" nothing dropped: {'met' if ok else 'NOT met'}"
        )
    return 0
