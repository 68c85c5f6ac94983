"""Fault tests (issue 7, item 1): each asserts that nothing is lost and robots stay safe.

* a robot agent SIGKILLed mid-task (fail and requeue): noticed within 1 s, the task
  follows ``on_robot_lost``, a peer crossing the dead robot's last pose keeps clear of it;
* the fleet service (``parkfleet serve``) SIGKILLed mid-task and restarted on the same
  data dir and Zenoh endpoint: robots hold or finish, tasks recovered, none duplicated;
* an agent cut off from its router (a ``parkfleet router`` process killed and restarted):
  it holds within ``link_timeout_s`` and resumes when the link returns;
* a stale pose source: the agent stops the robot;
* LONG (~1 min): a burst of 1000 tasks while robots come and go: every accepted task ends
  in a final state.

Real Zenoh over loopback, real SQLite files, real subprocesses; every process is stopped
and every session closed in ``finally`` blocks. Every wait is on a condition (``wait_for``),
with a generous bound that says why; the reaction times the issue states (lost within 1 s,
holding within the link timeout) are printed, not asserted: the machine is shared and
noisy. What is asserted about time follows from the logic (a robot never holds before its
pose is stale).
"""

from __future__ import annotations

import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
from support import park, read_line, wait_for, zenoh_fleet_service

from fleet.core.tasks import FleetEvent, RobotEvent, RobotStatus, TaskRequest, TaskStatus
from fleet.core.wire import Keys, Pose, RobotMode, encode
from fleet.io.processes import running_server
from fleet.io.settings import Settings, load_settings
from fleet.io.transport import open_session
from robot_agent.agent import RobotAgent
from robot_agent.clock import MonotonicClock
from sim_agent.drive import SimDrive
from sim_agent.fleet import SimFleet, Spawn

pytestmark = pytest.mark.integration

KEYS = Keys()
CLI = [sys.executable, "-m", "fleet.cli"]
FINAL = {"succeeded", "failed", "cancelled"}


@contextmanager
def child(*args: str, log: Path | None = None) -> Iterator[subprocess.Popen[bytes]]:
    """A ``parkfleet`` subprocess (stdout piped), SIGKILLed and reaped on exit."""
    err = log.open("ab") if log is not None else subprocess.DEVNULL
    proc = subprocess.Popen(
        [*CLI, *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=err,
        env=os.environ | {"PYTHONUNBUFFERED": "1"},
    )
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=10)
        if log is not None:
            err.close()  # type: ignore[union-attr]


@contextmanager
def sim_process(
    endpoint: str, spawns: list[Spawn], path: Path, time_scale: float = 4.0
) -> Iterator[subprocess.Popen[bytes]]:
    """``parkfleet sim`` with robots placed by a JSON spawn file; waits for its ready line."""
    path.write_text(
        json.dumps([{"id": s.robot_id, "x": s.x, "y": s.y, "theta": s.theta} for s in spawns])
    )
    args = ["sim", "--robots", str(len(spawns)), "--connect", endpoint]
    args += ["--time-scale", str(time_scale), "--spawn", str(path)]
    with child(*args, log=path.with_suffix(".log")) as proc:
        assert read_line(proc, 60).startswith("sim:")
        yield proc


# 1 -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("on_lost", ["fail", "requeue"])
def test_sigkilled_agent_is_noticed_its_task_follows_the_setting_and_peers_avoid_it(
    on_lost: str, router_endpoint: str, tmp_path: Path
) -> None:
    settings = load_settings(connect=[router_endpoint], task_timeout_s=60.0, on_robot_lost=on_lost)
    lost_at: list[float] = []

    def on_event(event: FleetEvent) -> None:
        robot = event.robot if isinstance(event, RobotEvent) else None
        if robot is not None and robot.robot_id == "dead" and robot.status == RobotStatus.LOST:
            lost_at.append(time.monotonic())

    goal = Pose(x=-5.0, y=0.0, theta=math.pi)
    with (
        zenoh_fleet_service(settings, tmp_path / "fleet.db") as service,
        open_session(settings, "client") as peer_session,
    ):
        service.add_listener(on_event)
        with sim_process(
            router_endpoint, [Spawn("dead", 0.0, 0.2, math.pi)], tmp_path / "dead.json"
        ) as victim:
            wait_for(lambda: len(service.robots()) == 1, 30, "the robot in the roster")
            task = service.submit(TaskRequest(goal=goal, direction="ccw"))
            wait_for(lambda: service.robot("dead").pose.x < -0.6, 30, "the robot under way")
            # the peer joins now (free, behind the victim on the same line)
            peer = SimFleet(
                peer_session, settings, [Spawn("peer", 4.0, 0.0, math.pi)], time_scale=5
            )
            with peer:
                peer.start()
                wait_for(lambda: "peer" in {r.robot_id for r in service.robots()}, 30, "peer")
                killed_at = time.monotonic()
                victim.send_signal(signal.SIGKILL)
                victim.wait(10)
                # Its TCP link closes at once; at the latest its 1 s lease runs out. 5 leases
                # leave room for a loaded machine and still catch a fleet that waits for the
                # default 10 s lease.
                wait_for(lambda: bool(lost_at), 5 * settings.lease_ms / 1000, "robot lost")
                noticed_after = lost_at[0] - killed_at

                def followed() -> bool:
                    t = service.task(task.id)
                    if on_lost == "fail":
                        return t.status == TaskStatus.FAILED
                    return t.status == TaskStatus.QUEUED or t.robot_id == "peer"

                wait_for(followed, 10, "the task to follow the setting")
                after_loss = service.task(task.id)
                last = service.robot("dead").pose
                if on_lost == "fail":
                    assert after_loss.status == TaskStatus.FAILED, after_loss
                    assert "lost" in (after_loss.reason or "")
                    crossing = service.submit(
                        TaskRequest(goal=goal, direction="ccw", robot_id="peer")
                    )
                else:
                    crossing = task  # requeued: the only free robot, the peer, takes it
                wait_for(
                    lambda: service.task(crossing.id).robot_id == "peer"
                    and service.task(crossing.id).status != TaskStatus.QUEUED,
                    30, "the peer to take the crossing task",
                )  # fmt: skip
                # The peer drives at the dead robot's last pose: it must keep clear of it,
                # watched until it is past that pose or done with the task.
                closest = math.inf

                def passed_or_done() -> bool:
                    nonlocal closest
                    x, y, _ = peer.drives["peer"].true_pose
                    closest = min(closest, math.hypot(x - last.x, y - last.y))
                    past = x < last.x - settings.avoidance.peer_radius
                    return past or service.task(crossing.id).status.final

                wait_for(passed_or_done, 120, "the peer to pass the dead robot", poll=0.002)
                kept = "dead" in peer.world.states()  # never forgotten by the peer
                final = service.task(crossing.id)
                peer_errors = peer.agents[0].tick_errors
        stored = service.tasks()
    radius = settings.profile.radius
    print(
        f"on_robot_lost={on_lost}: noticed after {noticed_after * 1000:.0f} ms; "
        f"peer closest {closest:.3f} m to the dead pose; crossing task {final.status}"
    )
    assert kept and peer_errors == 0
    assert closest > 2 * radius, f"peer came within {closest:.3f} m of the dead robot"
    if on_lost == "requeue":
        assert final.id == task.id and final.attempts == 2
    # nothing lost or duplicated: one row per submitted task
    assert len(stored) == (2 if on_lost == "fail" else 1)
    assert len({t.id for t in stored}) == len(stored)


# 3 -----------------------------------------------------------------------------------------
def test_agent_cut_off_from_its_router_holds_within_the_timeout_and_resumes() -> None:
    link_timeout = 1.0
    with child("router", "--listen", "tcp/127.0.0.1:0") as router:
        endpoint = read_line(router, 30).split()[-1]
        port = endpoint.rsplit(":", 1)[1]
        settings = load_settings(connect=[endpoint], link_timeout_s=link_timeout)
        with (
            open_session(settings, "client") as robot_session,
            open_session(settings, "client") as fleet_session,
            SimFleet(robot_session, settings, [Spawn("r1", 0.0, 0.0, 0.0)], time_scale=1) as sim,
        ):
            sim.start()
            agent, drive = sim.agents[0], sim.drives["r1"]
            message = park("r1", "far", (8.0, 6.0, 0.0))

            def mode() -> RobotMode | None:
                return agent.last.mode if agent.last is not None else None

            def acked() -> bool:
                fleet_session.put(KEYS.assignment("r1"), encode(message))
                return agent.last is not None and agent.last.task_id == "far"

            wait_for(acked, 10, "the assignment")
            # Router up, no fleet service, no peers: the robot keeps driving (its echo
            # through the router is the evidence) for two link timeouts of its own ticks
            # (time scale 1: ticks are real time, and more of it when the machine is slow).
            modes: list[RobotMode | None] = []
            assert agent.last is not None
            ticks_past = agent.last.seq + round(2 * link_timeout * settings.control_rate_hz)

            def driven_past_the_timeout() -> bool:
                modes.append(mode())
                return agent.last is not None and agent.last.seq >= ticks_past

            wait_for(driven_past_the_timeout, 60, "two link timeouts of ticks")
            assert set(modes) == {RobotMode.DRIVING}, Counter(modes)

            router.kill()  # the link is cut
            cut_at = time.monotonic()
            router.wait(10)
            # It holds within the link timeout (printed below); 5x that bounds a loaded run.
            wait_for(lambda: mode() is RobotMode.HOLDING, 5 * link_timeout, "the robot to hold")
            held_after = time.monotonic() - cut_at
            wait_for(lambda: (drive.right, drive.left) == (0.0, 0.0), 5, "wheels stopped")
            still = drive.true_pose
            # It stands still while cut off: a second of its ticks (50) at one pose.
            held_seq = agent.last.seq  # type: ignore[union-attr]
            wait_for(
                lambda: agent.last.seq >= held_seq + settings.control_rate_hz,  # type: ignore[union-attr]
                60, "a second of ticks on hold",
            )  # fmt: skip
            assert drive.true_pose == still
            assert mode() is RobotMode.HOLDING and agent.last.task_id == "far"  # type: ignore[union-attr]

            with child("router", "--listen", f"tcp/127.0.0.1:{port}") as again:
                assert read_line(again, 30).startswith("router listening")
                back_at = time.monotonic()
                wait_for(lambda: mode() is RobotMode.DRIVING, 30, "the robot to resume")
                resumed_after = time.monotonic() - back_at
                wait_for(lambda: drive.true_pose != still, 10, "the robot to move again")
                assert agent.last is not None and agent.last.task_id == "far"
                assert sim.link.losses == 1
                assert agent.tick_errors == 0 and agent.callback_errors == 0
    print(
        f"link cut: held after {held_after * 1000:.0f} ms (timeout {link_timeout:g} s); "
        f"resumed {resumed_after * 1000:.0f} ms after the router came back"
    )


# 4 -----------------------------------------------------------------------------------------
class FreezingDrive:
    """A real-time simulated drive whose pose source can freeze (stamps stop advancing)."""

    def __init__(self, start: tuple[float, float, float], settings: Settings) -> None:
        self.sim = SimDrive(start, settings.profile, MonotonicClock(), max_step=0.02)
        self.frozen: tuple[Pose, float] | None = None

    def read_pose(self) -> tuple[Pose, float]:
        reading = self.sim.read_pose()
        return self.frozen if self.frozen is not None else reading

    def command_wheels(self, right_rad_s: float, left_rad_s: float) -> None:
        self.sim.command_wheels(right_rad_s, left_rad_s)

    def stop(self) -> None:
        self.sim.stop()


def test_stale_pose_source_stops_the_robot_through_the_agent(client_settings: Settings) -> None:
    settings = client_settings.model_copy(update={"pose_stale_s": 0.3})
    drive = FreezingDrive((0.0, 0.0, 0.0), settings)
    with (
        open_session(settings, "client") as session,
        open_session(settings, "client") as fleet_session,
        RobotAgent("stale", drive, session, settings) as agent,
    ):
        agent.start()
        message = park("stale", "t1", (6.0, 4.0, 0.0))

        def acked() -> bool:
            fleet_session.put(KEYS.assignment("stale"), encode(message))
            return agent.last is not None and agent.last.mode is RobotMode.DRIVING

        wait_for(acked, 10, "driving")
        drive.frozen = drive.sim.read_pose()  # the localiser stops updating
        measured_at = drive.frozen[1]  # time.monotonic(), as the agent's clock
        wait_for(lambda: agent.last.mode is RobotMode.HOLDING, 10, "hold")  # type: ignore[union-attr]
        stopped_after = time.monotonic() - measured_at  # seen after the hold: not before it
        wait_for(lambda: (drive.sim.right, drive.sim.left) == (0.0, 0.0), 5, "wheels stopped")
        assert agent.last is not None and agent.last.task_id == "t1"
        drive.frozen = None  # fresh poses again: it drives on with the same task
        wait_for(lambda: agent.last.mode is RobotMode.DRIVING, 10, "resume")  # type: ignore[union-attr]
        assert agent.tick_errors == 0
    print(f"stale pose: held {stopped_after * 1000:.0f} ms after the last measurement")
    assert stopped_after > settings.pose_stale_s  # it held only once the pose was stale


# 2 -----------------------------------------------------------------------------------------
def test_service_sigkilled_mid_task_recovers_from_sqlite_without_loss_or_duplicates(
    tmp_path: Path,
) -> None:
    data = tmp_path / "data"
    goals = [(-6.0, 6.0, 0.0), (6.0, -6.0, 0.0)]
    with (
        (tmp_path / "serve.log").open("w") as log,
        running_server(data, stderr=log) as first,
    ):
        port = first.zenoh_endpoint.rsplit(":", 1)[1]
        endpoint = f"tcp/127.0.0.1:{port}"
        spawns = [Spawn("r1", 0.0, 1.0, 0.0), Spawn("r2", 0.0, -1.0, 0.0)]
        with sim_process(endpoint, spawns, tmp_path / "spawn.json", time_scale=2) as sim:
            with httpx.Client(base_url=first.url, timeout=10) as client:
                wait_for(lambda: len(client.get("/robots").json()) == 2, 30, "two robots")
                ids = []
                for i, (x, y, th) in enumerate(goals):
                    r = client.post(
                        "/tasks",
                        json={"goal": {"x": x, "y": y, "theta": th}, "direction": "ccw"},
                        headers={"Idempotency-Key": f"k{i}"},
                    )
                    assert r.status_code == 201, r.text
                    ids.append(r.json()["id"])
                wait_for(
                    lambda: all(client.get(f"/tasks/{i}").json()["status"] == "driving"
                                for i in ids),
                    30, "both tasks under way",
                )  # fmt: skip
            first.process.kill()  # SIGKILL mid-task
            first.process.wait(10)
            # The robots are cut off meanwhile: they hold (link test above) and say so.
            sim_log = (tmp_path / "spawn.log").read_text
            wait_for(lambda: "link to the fleet network lost" in sim_log(), 30, "robots hold")
            assert sim.poll() is None  # the robots survive the outage
            with (
                running_server(data, "--zenoh-listen", endpoint, stderr=log) as second,
                httpx.Client(base_url=second.url, timeout=10) as client,
            ):
                # a client retrying its POST with the same key gets the same task
                again = client.post(
                    "/tasks",
                    json={"goal": {"x": -6.0, "y": 6.0, "theta": 0.0}, "direction": "ccw"},
                    headers={"Idempotency-Key": "k0"},
                )
                assert again.status_code in (200, 201) and again.json()["id"] == ids[0]
                wait_for(
                    lambda: all(client.get(f"/tasks/{i}").json()["status"] in FINAL
                                for i in ids),
                    120, "both tasks to finish after the restart",
                )  # fmt: skip
                listed = client.get("/tasks").json()
                robots = {r["robot_id"]: r for r in client.get("/robots").json()}
    statuses = [t["status"] for t in listed] if isinstance(listed, list) else []
    if isinstance(listed, dict):  # paginated listing
        statuses = [t["status"] for t in listed.get("items", listed.get("tasks", []))]
    with sqlite3.connect(data / "parkfleet.db") as db:
        rows = db.execute("SELECT id, status FROM tasks").fetchall()
        created = db.execute(
            "SELECT task_id, COUNT(*) FROM task_history WHERE event = 'created' GROUP BY task_id"
        ).fetchall()
    db.close()
    assert sorted(r[0] for r in rows) == sorted(ids)  # none lost, none duplicated
    assert {r[1] for r in rows} == {"succeeded"}, rows
    assert statuses == ["succeeded", "succeeded"]
    assert all(n == 1 for _, n in created) and len(created) == 2
    assert {robots[r]["status"] for r in ("r1", "r2")} == {"arrived"}
