"""Multi-host: the fleet host and two robots in separate Linux network namespaces.

Topology (created by the test, torn down whatever happens)::

    ns robot-a  10.231.1.2 ──veth── 10.231.1.1 ┐
                                               ├ ns fleet host: parkfleet router
    ns robot-b  10.231.2.2 ──veth── 10.231.2.1 ┘

Each robot namespace only has its veth link to the fleet host (no route to the other
robot, no shared loopback): a state can cross from robot A to robot B only through the
router on the fleet host. Needs root and iproute2; skips with the reason otherwise.
"""

from __future__ import annotations

import itertools
import json
import os
import queue
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import pytest

pytestmark = pytest.mark.integration

PARKFLEET = Path(sys.executable).with_name("parkfleet")
CLI = [str(PARKFLEET)] if PARKFLEET.exists() else [sys.executable, "-m", "fleet.cli"]
ROBOTS = {"a": "alpha-1", "b": "bravo-1"}  # namespace suffix -> robot id (--id-prefix alpha-)
_runs = itertools.count()

# Watches the fleet from inside a namespace: prints which robots' states and liveliness
# tokens it saw (as JSON), once it has seen all the expected ones or after 30 s.
OBSERVER = """
import json, sys, threading
import zenoh
from fleet.io.settings import load_settings
from fleet.io.transport import open_session
from fleet.core.wire import Keys, RobotState
from fleet.io.decoder import Decoder

endpoint, expected = sys.argv[1], set(sys.argv[2].split(","))
keys, decoder, lock, states, alive = Keys(), Decoder("observer"), threading.Lock(), {}, set()
seen_all = threading.Event()

def check():
    if expected <= set(states) and expected <= alive:
        seen_all.set()

def on_state(sample):
    state = decoder.decode(RobotState, sample.payload.to_bytes())
    if state is not None and keys.robot_of(str(sample.key_expr)) == state.robot_id:
        with lock:
            states[state.robot_id] = state.pose.as_tuple()
            check()

def on_alive(sample):
    robot = keys.robot_of(str(sample.key_expr))
    with lock:
        (alive.add if sample.kind == zenoh.SampleKind.PUT else alive.discard)(robot)
        check()

with open_session(load_settings(connect=[endpoint]), "client") as session:
    sub = session.declare_subscriber(keys.all_states, on_state)
    tokens = session.liveliness().declare_subscriber(keys.all_alive, on_alive, history=True)
    seen_all.wait(30.0)  # bounds a hung run; the test checks what was seen
    tokens.undeclare()
    sub.undeclare()
with lock:
    print(json.dumps({"states": states, "alive": sorted(a for a in alive if a)}), flush=True)
"""


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, capture_output=True, text=True, timeout=30, check=False)


def _ip(*args: str) -> None:
    done = _run("ip", *args)
    if done.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {done.stderr.strip()}")


@dataclass
class Hosts:
    """Three namespaces (fleet host ``h``, robots ``a`` and ``b``) and their processes."""

    prefix: str
    created: list[str] = field(default_factory=list)
    procs: list[subprocess.Popen[str]] = field(default_factory=list)
    lines: dict[int, queue.Queue[str | None]] = field(default_factory=dict)
    errors: dict[int, queue.Queue[str | None]] = field(default_factory=dict)
    pumps: list[threading.Thread] = field(default_factory=list)

    def ns(self, host: str) -> str:
        return f"{self.prefix}{host}"

    def build(self) -> None:
        for host in ("h", "a", "b"):
            _ip("netns", "add", self.ns(host))
            self.created.append(self.ns(host))
            _ip("-n", self.ns(host), "link", "set", "lo", "up")
        for number, robot in enumerate(("a", "b"), start=1):
            # Created right inside the namespaces: the names never meet in the root one.
            far, near = "uplink", f"to-{robot}"
            _ip("link", "add", near, "netns", self.ns("h"), "type", "veth",
                "peer", "name", far, "netns", self.ns(robot))  # fmt: skip
            _ip("-n", self.ns("h"), "addr", "add", f"10.231.{number}.1/24", "dev", near)
            _ip("-n", self.ns(robot), "addr", "add", f"10.231.{number}.2/24", "dev", far)
            _ip("-n", self.ns("h"), "link", "set", near, "up")
            _ip("-n", self.ns(robot), "link", "set", far, "up")

    def start(self, host: str, args: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
        proc = subprocess.Popen(
            ["ip", "netns", "exec", self.ns(host), *args],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=os.environ | {"PYTHONUNBUFFERED": "1"} | env,
        )  # fmt: skip
        self.procs.append(proc)
        self.lines[proc.pid], self.errors[proc.pid] = queue.Queue(), queue.Queue()
        for stream, sink in ((proc.stdout, self.lines), (proc.stderr, self.errors)):
            pump = threading.Thread(target=_pump, args=(stream, sink[proc.pid]), daemon=True)
            pump.start()
            self.pumps.append(pump)
        return proc

    def stderr(self, proc: subprocess.Popen[str]) -> str:
        """What ``proc`` wrote on stderr so far."""
        errors = self.errors[proc.pid]
        return "".join(iter(lambda: errors.get_nowait() if not errors.empty() else None, None))

    def read_line(self, proc: subprocess.Popen[str], timeout: float) -> str:
        """The next line ``proc`` prints (fails the test after ``timeout`` s or at its exit)."""
        try:
            line = self.lines[proc.pid].get(timeout=timeout)
        except queue.Empty:
            line = None
        if line is None:
            proc.kill()
            proc.wait(timeout=10)
            raise AssertionError(
                f"no line from {proc.args!r} within {timeout} s: {self.stderr(proc)}"
            )
        return line

    def teardown(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs:
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
        for pump in self.pumps:
            pump.join(timeout=10)
        for proc in self.procs:
            for stream in (proc.stdout, proc.stderr):
                if stream is not None:
                    stream.close()
        for ns in reversed(self.created):  # deleting a namespace removes its veth ends
            _run("ip", "netns", "del", ns)


def _skip_or_fail(reason: str) -> None:
    if os.environ.get("CI") == "true":
        pytest.fail(f"multi-host tests cannot run in CI: {reason}")
    pytest.skip(reason)


def _skip_reason() -> str | None:
    if sys.platform != "linux":
        return "network namespaces need Linux"
    if os.geteuid() != 0:
        return "creating network namespaces needs root (run the suite as root)"
    if shutil.which("ip") is None:
        return "iproute2's `ip` is not installed"
    return None


@pytest.fixture
def hosts() -> Iterator[Hosts]:
    """Three network namespaces; skipped where they cannot be made locally, a failure under
    CI (as the browser tests: a skipped multi-host test would hide a broken deployment)."""
    reason = _skip_reason()
    if reason:
        _skip_or_fail(reason)
    env = Hosts(prefix=f"pf{os.getpid()}x{next(_runs)}")
    try:
        try:
            env.build()
        except RuntimeError as exc:
            _skip_or_fail(f"`ip netns` is not usable here: {exc}")
        yield env
    finally:
        env.teardown()
        left = set(_run("ip", "netns", "list").stdout.split()) & set(env.created)
        assert not left, f"namespaces left behind: {left}"


def _pump(stream: IO[str] | None, lines: queue.Queue[str | None]) -> None:
    """Lines of a child's stream into a queue; None at its end."""
    assert stream is not None
    for line in stream:
        lines.put(line)
    lines.put(None)


def _credentials(tmp_path: Path) -> Path:
    path = tmp_path / "users.txt"
    path.write_text("fleet:fleet-pw\n" + "".join(f"{r}:{r}-pw\n" for r in ROBOTS.values()))
    return path


@pytest.mark.parametrize("secured", [False, True], ids=["plain", "usrpwd+acl"])
def test_robot_states_cross_between_namespaces_through_the_fleet_host(
    hosts: Hosts, secured: bool, tmp_path: Path
) -> None:
    router_env: dict[str, str] = {}
    if secured:  # the router picks the security up from PARKFLEET_* settings
        router_env = {
            "PARKFLEET_ZENOH_CREDENTIALS_FILE": str(_credentials(tmp_path)),
            "PARKFLEET_ACL": "true",
        }
    router = hosts.start(
        "h",
        [*CLI, "router", "--listen", "tcp/10.231.1.1:7447", "--listen", "tcp/10.231.2.1:7447"],
        router_env,
    )
    locators = [hosts.read_line(router, 60.0).strip() for _ in range(2)]
    assert sorted(locators) == [
        "router listening on tcp/10.231.1.1:7447",
        "router listening on tcp/10.231.2.1:7447",
    ]

    def robot_env(robot: str) -> dict[str, str]:
        if not secured:
            return {}
        return {"PARKFLEET_ZENOH_USER": robot, "PARKFLEET_ZENOH_PASSWORD": f"{robot}-pw"}

    for number, (host, robot) in enumerate(ROBOTS.items(), start=1):
        spawn = tmp_path / f"{robot}.json"  # 3 m apart in the yard
        spawn.write_text(json.dumps([{"id": robot, "x": 3.0 * number - 4.5, "y": 0.0}]))
        sim = hosts.start(
            host,
            [*CLI, "sim", "--robots", "1", "--spawn", str(spawn),
             "--connect", f"tcp/10.231.{number}.1:7447"],
            robot_env(robot),
        )  # fmt: skip
        assert hosts.read_line(sim, 60.0).startswith(f"sim: 1 robots ({robot}")

    # Each observer runs in a robot's namespace (with that robot's identity when secured):
    # what it sees is what the robot next to it can see of the fleet.
    expected = ",".join(ROBOTS.values())
    observers = {
        robot: hosts.start(
            host,
            [sys.executable, "-c", OBSERVER, f"tcp/10.231.{number}.1:7447", expected],
            robot_env(robot),
        )
        for number, (host, robot) in enumerate(ROBOTS.items(), start=1)
    }
    views = {robot: json.loads(hosts.read_line(proc, 90.0)) for robot, proc in observers.items()}
    for proc in observers.values():
        assert proc.wait(timeout=15) == 0, hosts.stderr(proc)

    for robot, view in views.items():
        assert set(view["states"]) == set(ROBOTS.values()), f"{robot}'s namespace saw {view}"
        assert set(view["alive"]) == set(ROBOTS.values()), f"{robot}'s namespace saw {view}"
    # The two namespaces have no route to each other: only the fleet host joins them.
    assert (
        _run("ip", "netns", "exec", hosts.ns("a"), "ip", "route", "get", "10.231.2.2").returncode
        != 0
    )
    assert router.poll() is None
