"""Operator control over real Zenoh: ``parkfleet estop | pause | resume`` run as separate
processes stop and release simulated robots with no fleet service running at all, and a
running service takes up what they latched."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import StateWatcher, assign_until_acked, park, wait_for, zenoh_fleet_service

from fleet.core.wire import ErrorLevel, Keys, RobotMode
from fleet.io.processes import parkfleet_command
from fleet.io.settings import Settings
from fleet.io.transport import open_session
from sim_agent.fleet import SimFleet, Spawn

pytestmark = pytest.mark.integration


@pytest.fixture
def driving(
    client_settings: Settings,
) -> Iterator[tuple[SimFleet, StateWatcher]]:
    """Two simulated robots driving long tasks (real time), and a watcher of their states.
    No fleet service: the test plays its part by sending the assignments itself."""
    with (
        open_session(client_settings, "client") as robots,
        open_session(client_settings, "client") as tool,
        SimFleet(robots, client_settings, [Spawn("r1", -8, 0, 0), Spawn("r2", -8, 3, 0)]) as fleet,
    ):
        watcher = StateWatcher(tool)
        try:
            fleet.start()
            assign_until_acked(tool, watcher, park("r1", "t1", (8.0, 0.0, 0.0)))
            assign_until_acked(tool, watcher, park("r2", "t2", (8.0, 3.0, 0.0)))
            for rid in ("r1", "r2"):
                wait_for(lambda r=rid: moving(watcher, r), 10, f"{rid} driving")
            yield fleet, watcher
        finally:
            watcher.close()


def moving(watcher: StateWatcher, robot_id: str) -> bool:
    state = watcher.latest(robot_id)
    return state is not None and state.mode in (RobotMode.DRIVING, RobotMode.AVOIDING)


def in_mode(watcher: StateWatcher, robot_id: str, mode: RobotMode) -> bool:
    state = watcher.latest(robot_id)
    return state is not None and state.mode is mode


def parkfleet(endpoint: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``parkfleet ARGS --connect ENDPOINT`` to the end (its own Zenoh session)."""
    return subprocess.run(
        [*parkfleet_command(*args), "--connect", endpoint],
        capture_output=True,
        text=True,
        timeout=60,
        stdin=subprocess.DEVNULL,
    )


def last_seq(watcher: StateWatcher, robot_id: str) -> int:
    state = watcher.latest(robot_id)
    assert state is not None
    return state.seq


def test_estop_from_another_process_stops_every_robot_until_release(
    router_endpoint: str, driving: tuple[SimFleet, StateWatcher]
) -> None:
    fleet, watcher = driving
    done = parkfleet(router_endpoint, "estop", "--reason", "drill", "--issuer", "ops-1")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "r1: confirmed" in done.stdout and "r2: confirmed" in done.stdout

    for rid in ("r1", "r2"):  # the CLI saw it; this session sees it too, a moment later
        wait_for(lambda r=rid: in_mode(watcher, r, RobotMode.ESTOP), 10, f"{rid} e-stopped")
        state = watcher.latest(rid)
        assert state is not None
        assert state.u == 0.0 and state.omega == 0.0 and state.task_id == f"t{rid[1]}"
        assert state.detail == "emergency stop by ops-1: drill"
        assert [(e.code, e.level) for e in state.errors] == [("estop", ErrorLevel.FATAL)]
        drive = fleet.drives[rid]
        assert (drive.right, drive.left) == (0.0, 0.0)
    # Latched: 25 more ticks (half a second) later the robots have not moved an inch.
    poses = {rid: fleet.drives[rid].true_pose for rid in ("r1", "r2")}
    seqs = {rid: last_seq(watcher, rid) for rid in ("r1", "r2")}
    wait_for(lambda: all(last_seq(watcher, r) > seqs[r] + 25 for r in seqs), 10, "ticks")
    assert {rid: fleet.drives[rid].true_pose for rid in poses} == poses
    assert all(s.mode is RobotMode.ESTOP for r in seqs for s in watcher.since(r, seqs[r]))

    # A resume does not release an e-stop; the release does, and both drive on.
    assert parkfleet(router_endpoint, "resume", "--wait", "0").returncode == 0
    done = parkfleet(router_endpoint, "estop", "--release")
    assert done.returncode == 0, done.stdout + done.stderr
    for rid in ("r1", "r2"):
        wait_for(lambda r=rid: moving(watcher, r), 10, f"{rid} driving again")
    assert fleet.agents[0].tick_errors == 0 and fleet.agents[0].callback_errors == 0


def test_pause_one_robot_while_the_other_drives_on_then_resume(
    router_endpoint: str, driving: tuple[SimFleet, StateWatcher]
) -> None:
    _, watcher = driving
    done = parkfleet(router_endpoint, "pause", "--robot", "r1")
    assert done.returncode == 0, done.stdout + done.stderr
    wait_for(lambda: in_mode(watcher, "r1", RobotMode.PAUSED), 10, "r1 paused")
    state = watcher.latest("r1")
    assert state is not None and state.errors == []
    assert state.detail is not None and state.detail.startswith("paused by cli-")
    seq = last_seq(watcher, "r2")
    wait_for(lambda: last_seq(watcher, "r2") > seq + 10, 10, "r2 ticks")
    assert all(s.mode in (RobotMode.DRIVING, RobotMode.AVOIDING) for s in watcher.since("r2", seq))
    done = parkfleet(router_endpoint, "resume", "--robot", "r1")
    assert done.returncode == 0, done.stdout + done.stderr
    wait_for(lambda: moving(watcher, "r1"), 10, "r1 driving again")


def test_a_robot_that_does_not_answer_is_reported_and_the_exit_code_says_so(
    router_endpoint: str, driving: tuple[SimFleet, StateWatcher]
) -> None:
    done = parkfleet(router_endpoint, "estop", "--robot", "ghost", "--wait", "0.5")
    assert done.returncode == 1
    assert "ghost: NOT confirmed" in done.stdout
    _, watcher = driving
    assert moving(watcher, "r1")  # a command for another robot changes nothing here


def test_estop_of_the_fleet_named_reaches_its_robots_and_no_other(
    router_endpoint: str, client_settings: Settings
) -> None:
    """``--fleet yard`` addresses fleet ``yard``; without it the settings' fleet (``default``)
    has no robot online: exit 1, said on stderr."""
    yard = client_settings.model_copy(update={"fleet_name": "yard"})
    with (
        open_session(yard, "client") as robots,
        open_session(yard, "client") as tool,
        SimFleet(robots, yard, [Spawn("r1", -8, 0, 0), Spawn("r2", -8, 3, 0)]) as fleet,
    ):
        watcher = StateWatcher(tool, Keys("yard"))
        try:
            fleet.start()
            for rid in ("r1", "r2"):
                wait_for(lambda r=rid: watcher.latest(r) is not None, 10, f"{rid} reporting")
            done = parkfleet(router_endpoint, "estop")  # fleet "default": nobody there
            assert done.returncode == 1, done.stdout + done.stderr
            assert "no robot of fleet default is online; nothing confirmed" in done.stderr
            assert all(in_mode(watcher, r, RobotMode.IDLE) for r in ("r1", "r2"))

            done = parkfleet(router_endpoint, "estop", "--fleet", "yard")
            assert done.returncode == 0, done.stdout + done.stderr
            assert "of fleet yard" in done.stdout
            assert "r1: confirmed" in done.stdout and "r2: confirmed" in done.stdout
            for rid in ("r1", "r2"):
                wait_for(lambda r=rid: in_mode(watcher, r, RobotMode.ESTOP), 10, f"{rid} stopped")
            done = parkfleet(router_endpoint, "estop", "--release", "--fleet", "yard")
            assert done.returncode == 0, done.stdout + done.stderr
        finally:
            watcher.close()


def test_a_robot_online_that_does_not_confirm_is_named_and_the_exit_code_is_1(
    router_endpoint: str, client_settings: Settings
) -> None:
    """A liveliness token with no agent behind it (a hung robot): the others confirm, it is
    named on stderr."""
    keys = Keys()
    with (
        open_session(client_settings, "client") as robots,
        open_session(client_settings, "client") as hung,
        open_session(client_settings, "client") as tool,
        SimFleet(robots, client_settings, [Spawn("r1", -8, 0, 0)]) as fleet,
    ):
        token = hung.liveliness().declare_token(f"{keys.root}/alive/r9")
        watcher = StateWatcher(tool)
        try:
            fleet.start()
            wait_for(lambda: watcher.latest("r1") is not None, 10, "r1 reporting")
            done = parkfleet(router_endpoint, "pause", "--wait", "1")
            assert done.returncode == 1, done.stdout + done.stderr
            assert "r1: confirmed" in done.stdout and "r9: NOT confirmed" in done.stdout
            assert "not confirmed by r9" in done.stderr
            done = parkfleet(router_endpoint, "resume", "--wait", "0")
            assert done.returncode == 0 and "not confirmed (--wait 0)" in done.stdout
        finally:
            watcher.close()
            token.undeclare()


def test_wrong_ids_are_refused_before_anything_is_sent(router_endpoint: str) -> None:
    done = parkfleet(router_endpoint, "estop", "--robot", "r*")
    assert done.returncode == 2 and "invalid robot id" in done.stderr
    done = parkfleet(router_endpoint, "estop", "--fleet", "a/b")
    assert done.returncode == 2 and "invalid fleet name" in done.stderr


def test_the_service_takes_up_a_cli_estop_for_a_late_joiner_and_its_release(
    router_endpoint: str, client_settings: Settings, tmp_path: Path
) -> None:
    """``parkfleet estop`` from another process while the service runs: the service sees it
    on the control key, tells a robot that joins later, and stops once the CLI releases."""
    with (
        zenoh_fleet_service(client_settings, tmp_path / "fleet.db") as service,
        open_session(client_settings, "client") as robots,
        open_session(client_settings, "client") as tool,
        SimFleet(robots, client_settings, [Spawn("r1", -8, 0, 0)]) as first,
    ):
        watcher = StateWatcher(tool)
        try:
            first.start()
            wait_for(lambda: watcher.latest("r1") is not None, 10, "r1 reporting")
            done = parkfleet(router_endpoint, "estop", "--reason", "drill", "--issuer", "ops-1")
            assert done.returncode == 0, done.stdout + done.stderr
            wait_for(lambda: service.control_state().fleet.estop, 10, "the service saw it")
            with SimFleet(robots, client_settings, [Spawn("r2", -8, 3, 0)]) as late:
                late.start()
                wait_for(lambda: in_mode(watcher, "r2", RobotMode.ESTOP), 10, "r2 e-stopped")
                state = watcher.latest("r2")
                assert state is not None and state.detail is not None
                assert state.detail == "emergency stop by fleet-service: drill (ops-1)"
                done = parkfleet(router_endpoint, "estop", "--release", "--issuer", "ops-1")
                assert done.returncode == 0, done.stdout + done.stderr
                wait_for(lambda: not service.control_state().fleet.estop, 10, "released")
                wait_for(lambda: in_mode(watcher, "r2", RobotMode.IDLE), 10, "r2 released")
                seq = last_seq(watcher, "r2")  # and the service does not e-stop it again
                wait_for(lambda: last_seq(watcher, "r2") > seq + 50, 10, "r2 ticks")
                assert all(s.mode is RobotMode.IDLE for s in watcher.since("r2", seq))
            assert service.counters["control_adopted"] == 2
        finally:
            watcher.close()
