"""``parkfleet bench zenoh``: state delivery of N simulated robots through a router.

For each N (10, 100, 1000 by default) a separate process runs ``parkfleet sim --robots N
--rate 10`` (full robot agents: idle robots still tick, publish their state at 10 Hz and
subscribe to every peer's state) connected to a router in this process; one subscriber
(a client session of this process, so every sample crosses the router) decodes every
state. Measured over a window after a warm-up:

* ``delivered_per_s`` -- states decoded per second (expected N x 10);
* ``age_p50_ms`` / ``age_p99_ms`` -- age of each robot's latest state when it arrives
  (receive wall time - sender stamp: publisher -> router -> subscriber latency, including
  queueing and the sender's encode);
* ``staleness_p50_ms`` / ``staleness_p99_ms`` -- sampled every 50 ms, age of the latest
  state held per robot (includes the up-to-100 ms publish interval);
* ``cpu_router_sub`` / ``cpu_robots`` -- CPU time / wall time (1.0 = one core) of this
  process (router + subscriber) and of the robots' process.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from fleet.core.wire import Keys, RobotState
from fleet.io.decoder import Decoder
from fleet.io.settings import load_settings
from fleet.io.transport import listening_locators, open_session, tcp_endpoint

DEFAULT_SIZES = (10, 100, 1000)
RATE_HZ = 10.0


def _proc_cpu_seconds(pid: int) -> float:
    """utime + stime [s] of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class _Collector:
    """Subscriber callback: decode every state, record its age on arrival."""

    def __init__(self, keys: Keys) -> None:
        self.keys = keys
        self.decoder = Decoder("bench")
        self.lock = threading.Lock()
        self.recording = False
        self.ages: list[float] = []
        self.count = 0
        self.latest: dict[str, float] = {}
        self.errors = 0

    def __call__(self, sample: Any) -> None:
        try:
            state = self.decoder.decode(RobotState, sample.payload.to_bytes())
            now = time.time()
            if state is None:
                return
            with self.lock:
                self.latest[state.robot_id] = state.stamp
                if self.recording:
                    self.count += 1
                    self.ages.append(now - state.stamp)
        except Exception:
            self.errors += 1


def _measure(
    endpoint: str, fleet: str, robots: int, warmup: float, window: float
) -> dict[str, Any]:
    keys = Keys(fleet)
    settings = load_settings(connect=[endpoint], fleet_name=fleet)
    collector = _Collector(keys)
    env = os.environ | {"PARKFLEET_FLEET_NAME": fleet}
    cmd = [
        sys.executable, "-m", "fleet.cli", "sim", "--robots", str(robots),
        "--rate", str(RATE_HZ), "--connect", endpoint, "--spawn", "grid", "--id-prefix", "b",
    ]  # fmt: skip
    with open_session(settings, "client") as session:
        sub = session.declare_subscriber(keys.all_states, collector)
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            assert proc.stdout is not None
            proc.stdout.readline()  # "sim: N robots ..." once every agent is declared
            time.sleep(warmup)
            staleness: list[float] = []
            with collector.lock:
                collector.recording = True
            wall0, cpu0, child0 = time.monotonic(), time.process_time(), _proc_cpu_seconds(proc.pid)
            end = wall0 + window
            while time.monotonic() < end:
                time.sleep(0.05)
                now = time.time()
                with collector.lock:
                    stamps = list(collector.latest.values())
                staleness.extend(now - s for s in stamps)
            with collector.lock:
                collector.recording = False
            wall = time.monotonic() - wall0
            cpu = time.process_time() - cpu0
            child_cpu = _proc_cpu_seconds(proc.pid) - child0
        finally:
            proc.send_signal(signal.SIGTERM)
            try:
                _, err = proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                _, err = proc.communicate()
            sub.undeclare()  # type: ignore[no-untyped-call]
    if proc.returncode != 0:
        raise RuntimeError(f"sim process failed ({proc.returncode}): {err.decode()[-2000:]}")
    ages = np.asarray(collector.ages) * 1000.0
    stale = np.asarray(staleness) * 1000.0

    def pct(a: np.ndarray[Any, Any], q: float) -> float:
        return float(np.percentile(a, q)) if a.size else float("nan")

    return {
        "robots": robots,
        "rate_hz": RATE_HZ,
        "delivered_per_s": collector.count / wall,
        "expected_per_s": robots * RATE_HZ,
        "age_p50_ms": pct(ages, 50),
        "age_p99_ms": pct(ages, 99),
        "age_max_ms": pct(ages, 100),
        "staleness_p50_ms": pct(stale, 50),
        "staleness_p99_ms": pct(stale, 99),
        "robots_seen": len(collector.latest),
        "cpu_router_sub": cpu / wall,
        "cpu_robots": child_cpu / wall,
        "dropped": collector.decoder.dropped_total + collector.errors,
        "window_s": wall,
    }


def run(sizes: list[int], warmup: float, window: float, as_json: bool = False) -> int:
    """Measure each robot count in ``sizes`` and print the rows (table or JSON)."""
    rows = []
    router_settings = load_settings(listen=["tcp/127.0.0.1:0"])
    with open_session(router_settings, "router") as router:
        endpoint = tcp_endpoint(listening_locators(router))
        for i, n in enumerate(sizes):
            row = _measure(endpoint, f"bench{i}", n, warmup, window)
            rows.append(row)
            if not as_json:
                print(
                    f"{n:>5} robots: delivered {row['delivered_per_s']:8.0f}/s "
                    f"(expected {row['expected_per_s']:.0f}/s), "
                    f"age p50 {row['age_p50_ms']:6.2f} ms "
                    f"p99 {row['age_p99_ms']:6.2f} ms, staleness p99 "
                    f"{row['staleness_p99_ms']:6.1f} ms, CPU router+sub "
                    f"{row['cpu_router_sub']:.2f} robots {row['cpu_robots']:.2f}",
                    flush=True,
                )
    if as_json:
        print(json.dumps({"rows": rows}))
    else:
        target = next((r for r in rows if r["robots"] == 1000), None)
        if target is not None:
            ok = target["age_p99_ms"] < 50.0
            print(
                f"target 1000 robots @ 10 Hz, p99 age < 50 ms: "
                f"{'met' if ok else 'NOT met'} ({target['age_p99_ms']:.1f} ms)"
            )
    return 0
