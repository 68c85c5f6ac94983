"""Robot agents and simulated robots on real Zenoh over loopback (one router per test)."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh
from support import StateWatcher, assign_until_acked, park, read_line, wait_for

from fleet.core.params import Gains, Tolerance
from fleet.core.step import pose_error
from fleet.core.wire import (
    CancelAssignment,
    ControlAction,
    ControlCommand,
    Keys,
    Obstacle,
    ObstacleSet,
    Pose,
    RobotMode,
    encode,
)
from fleet.io.settings import Settings
from fleet.io.transport import open_session
from sim_agent.fleet import SimFleet, Spawn

pytestmark = pytest.mark.integration

KEYS = Keys()
PARKFLEET = Path(sys.executable).with_name("parkfleet")
CLI = [str(PARKFLEET)] if PARKFLEET.exists() else [sys.executable, "-m", "fleet.cli"]
GAINS = Gains(kx=1.0, ky=2.0, ktheta=1.0)
TOL = Tolerance(position=0.1, heading=0.1)


@pytest.fixture
def fleet_session(client_settings: Settings) -> Iterator[Any]:
    with open_session(client_settings, "client") as session:
        yield session


@pytest.fixture
def watcher(client_settings: Settings) -> Iterator[tuple[Any, StateWatcher]]:
    """A second client session (the "fleet service" side) with a state watcher."""
    with open_session(client_settings, "client") as session:
        w = StateWatcher(session)
        try:
            yield session, w
        finally:
            w.close()


@pytest.fixture
def processes() -> Iterator[list[subprocess.Popen[bytes]]]:
    """Subprocesses started by a test; killed and reaped whatever happens."""
    procs: list[subprocess.Popen[bytes]] = []
    try:
        yield procs
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
            proc.communicate(timeout=10)


def start_cli(procs: list[subprocess.Popen[bytes]], *args: str) -> subprocess.Popen[bytes]:
    proc = subprocess.Popen(
        [*CLI, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=os.environ | {"PYTHONUNBUFFERED": "1"},
    )
    procs.append(proc)
    return proc


# (a) -------------------------------------------------------------------------------------
def test_agent_given_an_assignment_arrives_within_tolerance(
    client_settings: Settings, fleet_session: Any, watcher: tuple[Any, StateWatcher]
) -> None:
    service, states = watcher
    goal = (1.5, 1.0, math.pi / 2)
    with SimFleet(fleet_session, client_settings, [Spawn("r1", 0, 0, 0)], time_scale=10) as fleet:
        fleet.start()
        assign_until_acked(service, states, park("r1", "t1", goal))
        wait_for(
            lambda: (s := states.latest("r1")) is not None and s.mode is RobotMode.ARRIVED,
            60.0,
            "arrival",
        )
        final = states.latest("r1")
        true_pose = fleet.drives["r1"].true_pose
    assert (
        final is not None
        and final.task_id == "t1"
        and final.goal == Pose(x=1.5, y=1.0, theta=goal[2])
    )
    for pose in (final.pose.as_tuple(), true_pose):
        x_e, y_e, theta_e = pose_error(*pose, *goal, False)
        assert math.hypot(x_e, y_e) < TOL.position and abs(theta_e) < TOL.heading
    moved = states.since("r1", -1)
    assert any(s.mode is RobotMode.DRIVING for s in moved)
    assert fleet.agents[0].tick_errors == 0 and fleet.agents[0].callback_errors == 0


# (b) -------------------------------------------------------------------------------------
def test_two_agents_on_crossing_paths_keep_a_minimum_separation(
    client_settings: Settings, watcher: tuple[Any, StateWatcher]
) -> None:
    service, states = watcher
    radius = client_settings.profile.radius
    # separate sessions: each robot only knows the other through Zenoh
    with (
        open_session(client_settings, "client") as s_a,
        open_session(client_settings, "client") as s_b,
        SimFleet(s_a, client_settings, [Spawn("a", -3.0, 0.0, 0.0)], time_scale=5) as fa,
        SimFleet(s_b, client_settings, [Spawn("b", 0.0, -3.0, math.pi / 2)], time_scale=5) as fb,
    ):
        fa.start()
        fb.start()
        # 4.2 m apart: not yet in each other's cells (a peer is heard within one cell size)
        wait_for(lambda: "a" in fa.world.states() and "b" in fb.world.states(), 10, "ticking")
        assign_until_acked(service, states, park("a", "ta", (3.0, 0.0, 0.0)))
        assign_until_acked(service, states, park("b", "tb", (0.0, 3.0, math.pi / 2)))
        closest = math.inf
        # ~30 s of simulated time, counted in the robots' own ticks (50 Hz), not wall time
        ticks = round(30.0 * client_settings.control_rate_hz)
        agents = (fa.agents[0], fb.agents[0])
        until = [a.last.seq + ticks if a.last is not None else ticks for a in agents]

        def sampled_30_s() -> bool:
            nonlocal closest
            (ax, ay, _), (bx, by, _) = fa.drives["a"].true_pose, fb.drives["b"].true_pose
            closest = min(closest, math.hypot(ax - bx, ay - by))
            return all(
                a.last is not None and a.last.seq >= u for a, u in zip(agents, until, strict=True)
            )

        wait_for(sampled_30_s, 120, "30 s of simulated time", poll=0.001)
        progress_a = fa.drives["a"].true_pose[0] + 3.0
        progress_b = fb.drives["b"].true_pose[1] + 3.0
    assert closest > 2 * radius, f"robots came within {closest:.3f} m"
    assert set(fa.world.states()) == set(fb.world.states()) == {"a", "b"}  # met on their cells
    assert progress_a > 1.0 and progress_b > 1.0  # they really drove at each other
    modes = {s.mode for rid in ("a", "b") for s in states.since(rid, -1)}
    assert RobotMode.AVOIDING in modes


# (c) -------------------------------------------------------------------------------------
def test_sigkilled_agent_process_is_seen_gone(
    router_endpoint: str, fleet_session: Any, processes: list[subprocess.Popen[bytes]]
) -> None:
    events: list[tuple[zenoh.SampleKind, str, float]] = []
    lock = threading.Lock()

    def on_alive(sample: Any) -> None:
        with lock:
            events.append((sample.kind, str(sample.key_expr), time.monotonic()))

    def seen(kind: zenoh.SampleKind) -> list[float]:
        with lock:
            return [t for k, key, t in events if k == kind and key == KEYS.alive("kill-1")]

    sub = fleet_session.liveliness().declare_subscriber(KEYS.all_alive, on_alive, history=True)
    try:
        proc = start_cli(processes, "sim", "--robots", "1", "--connect", router_endpoint,
                         "--id-prefix", "kill-", "--time-scale", "5")  # fmt: skip
        wait_for(lambda: bool(seen(zenoh.SampleKind.PUT)), 30, "the robot's liveliness token")
        killed_at = time.monotonic()
        proc.send_signal(signal.SIGKILL)
        # Its TCP link closes at once (a few ms); at the latest its 1 s lease runs out. 5
        # leases leave room for a loaded machine and still catch the default 10 s lease.
        wait_for(lambda: bool(seen(zenoh.SampleKind.DELETE)), 5.0, "the token to disappear")
        gone_after = seen(zenoh.SampleKind.DELETE)[0] - killed_at
    finally:
        sub.undeclare()
    print(f"killed agent seen gone after {gone_after * 1000:.0f} ms")


# (d) -------------------------------------------------------------------------------------
BLOCK = zenoh.CongestionControl.BLOCK  # this test is about handling, not delivery under load
JUNK = [
    b"",
    b"\xff\xfe not utf8",
    b"{not json",
    b"[]",
    b'{"v": 1, "kind": "park"}',
    b'{"v": 2, "kind": "cancel", "robot_id": "r1", "task_id": "t1"}',
    b'{"v": 1, "kind": "launch", "robot_id": "r1", "task_id": "x"}',
    b"x" * 70_000,
]


def test_malformed_payload_on_assignment_key_changes_nothing(
    client_settings: Settings, fleet_session: Any, watcher: tuple[Any, StateWatcher]
) -> None:
    service, states = watcher
    with SimFleet(
        fleet_session, client_settings, [Spawn("r1", 1.0, 2.0, 0.3)], time_scale=5
    ) as fleet:
        fleet.start()
        agent = fleet.agents[0]
        wait_for(lambda: states.latest("r1") is not None, 10, "first state")
        for junk in JUNK:
            service.put(KEYS.assignment("r1"), junk, congestion_control=BLOCK)
        wait_for(lambda: agent.decoder.dropped_total == len(JUNK), 10, "every payload dropped")
        mark = states.latest("r1").seq  # type: ignore[union-attr]
        wait_for(lambda: len(states.since("r1", mark)) >= 20, 10, "more states")
        after = states.since("r1", mark)
        assert {s.mode for s in after} == {RobotMode.IDLE}
        assert {s.task_id for s in after} == {None}
        assert {s.pose for s in after} == {Pose(x=1.0, y=2.0, theta=0.3)}
        # still listening: a valid assignment is obeyed, and junk during a task is harmless
        assign_until_acked(service, states, park("r1", "t1", (3.0, 2.0, 0.3)))
        for junk in JUNK:
            service.put(KEYS.assignment("r1"), junk, congestion_control=BLOCK)
        wait_for(lambda: agent.decoder.dropped_total == 2 * len(JUNK), 10, "dropped again")
        mark = states.latest("r1").seq  # type: ignore[union-attr]
        wait_for(lambda: len(states.since("r1", mark)) >= 20, 10, "more states")
        assert {(s.task_id, s.goal) for s in states.since("r1", mark)} == {
            ("t1", Pose(x=3.0, y=2.0, theta=0.3))
        }
    assert agent.tick_errors == 0 and agent.callback_errors == 0
    assert agent.decoder.dropped["invalid"] == 2 * (len(JUNK) - 1)
    assert agent.decoder.dropped["oversized"] == 2


# (e) -------------------------------------------------------------------------------------
def test_sim_cli_exits_cleanly_on_sigterm_and_its_robots_leave(
    router_endpoint: str, fleet_session: Any, processes: list[subprocess.Popen[bytes]]
) -> None:
    alive: set[str] = set()
    lock = threading.Lock()

    def on_alive(sample: Any) -> None:
        with lock:
            key = str(sample.key_expr)
            (alive.add if sample.kind == zenoh.SampleKind.PUT else alive.discard)(key)

    sub = fleet_session.liveliness().declare_subscriber(KEYS.all_alive, on_alive, history=True)
    try:
        proc = start_cli(processes, "sim", "--robots", "3", "--connect", router_endpoint,
                         "--time-scale", "5", "--spawn", "random", "--seed", "3")  # fmt: skip
        assert read_line(proc, 30).startswith("sim: 3 robots")
        wait_for(lambda: len(alive) == 3, 10, "three liveliness tokens")
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            raise AssertionError("parkfleet sim hung after SIGTERM") from None
        assert proc.returncode == 0, err.decode()
        wait_for(lambda: not alive, 2, "tokens undeclared")
    finally:
        sub.undeclare()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_router_and_agent_cli_exit_cleanly(
    sig: signal.Signals, processes: list[subprocess.Popen[bytes]]
) -> None:
    router = start_cli(processes, "router", "--listen", "tcp/127.0.0.1:0")
    line = read_line(router, 30)
    assert line.startswith("router listening on tcp/127.0.0.1:")
    endpoint = line.split()[-1]
    agent = start_cli(processes, "agent", "--id", "solo", "--drive", "sim", "--connect", endpoint)
    assert read_line(agent, 30).startswith("agent solo running")
    for proc in (agent, router):
        proc.send_signal(sig)
        try:
            _, err = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"{proc.args!r} hung after {sig.name}") from None
        assert proc.returncode == 0, err.decode()


def test_agent_cli_without_router_fails_fast(processes: list[subprocess.Popen[bytes]]) -> None:
    proc = start_cli(
        processes, "agent", "--id", "r1", "--drive", "sim", "--connect", "tcp/127.0.0.1:9"
    )
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2 and b"Is the fleet host" in err


def test_late_joiner_gets_obstacles_by_query_and_follows_updates(
    client_settings: Settings, fleet_session: Any, watcher: tuple[Any, StateWatcher]
) -> None:
    service, _ = watcher
    first = ObstacleSet(obstacles=[Obstacle(x=1.0, y=2.0, radius=0.5)])
    queryable = service.declare_queryable(
        KEYS.obstacles, lambda query: query.reply(KEYS.obstacles, encode(first))
    )
    try:
        # The robot queries once as it joins: let the queryable's declaration reach the
        # robot's session through the router first (it takes a moment on a busy machine).
        wait_for(
            lambda: any(r.ok is not None for r in fleet_session.get(KEYS.obstacles, timeout=2.0)),
            30, "the obstacle queryable, seen from the robot's session",
        )  # fmt: skip
        with SimFleet(fleet_session, client_settings, [Spawn("r1", 0, 0, 0)]) as fleet:
            wait_for(lambda: fleet.world.obstacles().shape[1] == 1, 10, "queried obstacles")
            update = ObstacleSet(obstacles=[Obstacle(x=5, y=5), Obstacle(x=-5, y=5)])
            service.put(KEYS.obstacles, encode(update), congestion_control=BLOCK)
            wait_for(lambda: fleet.world.obstacles().shape[1] == 2, 10, "obstacle update")
    finally:
        queryable.undeclare()


def test_a_deposed_leaders_assignments_and_commands_are_dropped_operators_still_obeyed(
    client_settings: Settings, fleet_session: Any, watcher: tuple[Any, StateWatcher]
) -> None:
    """Fencing term on real Zenoh: after term 2 was heard, term-1 assignments, cancels and
    service commands are dropped and counted; an operator's term-0 e-stop is obeyed."""
    service, states = watcher
    with SimFleet(fleet_session, client_settings, [Spawn("r1", 0, 0, 0)], time_scale=5) as fleet:
        fleet.start()
        agent = fleet.agents[0]
        assign_until_acked(service, states, park("r1", "t2", (3.0, 0.0, 0.0), term=2))
        for message in (
            park("r1", "t1", (-3.0, 0.0, 0.0), term=1),  # a deposed leader's new task
            park("r1", "t2", (-3.0, 0.0, 0.0), term=1, revision=5),  # and a "re-plan"
            CancelAssignment(robot_id="r1", task_id="t2", term=1),
        ):
            service.put(KEYS.assignment("r1"), encode(message), congestion_control=BLOCK)
        stale = ControlCommand(
            command=ControlAction.PAUSE, robot_id="r1", issuer="fleet-service", seq=1, stamp=0.0,
            term=1,
        )  # fmt: skip
        service.put(KEYS.control("r1"), encode(stale), congestion_control=BLOCK)
        wait_for(lambda: agent.fence.dropped == 4, 10, "four stale messages dropped")
        mark = states.latest("r1").seq  # type: ignore[union-attr]
        wait_for(lambda: len(states.since("r1", mark)) >= 10, 10, "more states")
        after = states.since("r1", mark)
        assert {(s.task_id, s.revision) for s in after} == {("t2", 0)}
        assert RobotMode.PAUSED not in {s.mode for s in after}
        estop = ControlCommand(command=ControlAction.ESTOP, issuer="cli", seq=1, stamp=0.0)
        service.put(KEYS.control(), encode(estop), congestion_control=BLOCK)
        wait_for(
            lambda: (s := states.latest("r1")) is not None and s.mode is RobotMode.ESTOP,
            10,
            "the operator's e-stop obeyed",
        )
    assert agent.fence.highest == 2 and agent.fence.dropped == 4
