"""Task life cycle over real Zenoh with simulated robots (``parkfleet sim`` subprocesses).

The service runs in this process (client session to the test router, SQLite store in
tmp_path); robots are a time-scaled ``parkfleet sim`` process spawned from a JSON file.
"""

from __future__ import annotations

import json
import signal
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from support import wait_for, zenoh_fleet_service

from fleet.core.tasks import RobotStatus, Task, TaskRequest, TaskStatus
from fleet.core.wire import Keys, Obstacle, ObstacleSet, Pose, RobotState, encode
from fleet.io.processes import sim_command, terminate
from fleet.io.settings import load_settings
from fleet.io.transport import open_session
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore

pytestmark = pytest.mark.integration

TIME_SCALE = 4.0


@contextmanager
def sim_robots(
    endpoint: str, tmp_path: Path, robots: list[tuple[str, float, float, float]]
) -> Iterator[subprocess.Popen[bytes]]:
    spawn = tmp_path / "spawn.json"
    spawn.write_text(json.dumps([{"id": r, "x": x, "y": y, "theta": t} for r, x, y, t in robots]))
    proc = subprocess.Popen(
        sim_command(endpoint, len(robots), time_scale=TIME_SCALE, spawn=str(spawn)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        yield proc
    finally:
        terminate(proc)
        if proc.stderr is not None:
            proc.stderr.close()


def status_of(service: FleetService, task: Task) -> TaskStatus:
    return service.task(task.id).status


def test_task_succeeds_and_every_transition_is_stored(router_endpoint: str, tmp_path: Path) -> None:
    settings = load_settings(connect=[router_endpoint], task_timeout_s=60.0)
    with (
        zenoh_fleet_service(settings, tmp_path / "var" / "parkfleet.db") as service,
        sim_robots(router_endpoint, tmp_path, [("r1", 0.0, 0.0, 0.0), ("r2", 0.0, 4.0, 0.0)]),
    ):
        wait_for(lambda: len(service.robots()) == 2, 20, "two robots in the roster")
        service.set_obstacles([Obstacle(x=-5.0, y=-5.0, radius=1.0)])
        task = service.submit(
            TaskRequest(goal=Pose(x=2.0, y=-1.0, theta=0.5)), idempotency_key="once"
        )
        assert (
            service.submit(
                TaskRequest(goal=Pose(x=2.0, y=-1.0, theta=0.5)), idempotency_key="once"
            ).id
            == task.id
        )
        wait_for(lambda: status_of(service, task).final, 60, "the task to finish")
        done = service.task(task.id)
        assert done.status == TaskStatus.SUCCEEDED, done.reason
        assert done.robot_id == "r1"  # the nearer robot, by predicted time
        robot = service.robot("r1")
        assert robot.status == RobotStatus.ARRIVED
        assert abs(robot.pose.x - 2.0) < 0.1 and abs(robot.pose.y + 1.0) < 0.1
        assert len(service.path(task.id)) > 10
        reopened = SqliteTaskStore(tmp_path / "var" / "parkfleet.db")  # a second connection
        try:
            history = [ev for _, ev, _ in reopened.history(task.id)]
        finally:
            reopened.close()
        assert history == ["created", "assigned", "acknowledged", "succeeded"]


def test_cancel_stops_the_robot(router_endpoint: str, tmp_path: Path) -> None:
    settings = load_settings(connect=[router_endpoint], task_timeout_s=60.0)
    with (
        zenoh_fleet_service(settings, tmp_path / "var" / "parkfleet.db") as service,
        sim_robots(router_endpoint, tmp_path, [("r1", 0.0, 0.0, 0.0)]),
    ):
        wait_for(lambda: len(service.robots()) == 1, 20, "the robot")
        task = service.submit(TaskRequest(goal=Pose(x=-8.0, y=8.0, theta=0.0), robot_id="r1"))
        wait_for(lambda: status_of(service, task) == TaskStatus.DRIVING, 20, "driving")
        cancelled = service.cancel(task.id)
        assert cancelled.status == TaskStatus.CANCELLED
        wait_for(
            lambda: service.robot("r1").status == RobotStatus.HOLDING,
            20,
            "the robot to hold",
        )
        held = service.robot("r1")
        # It stands still: another 0.3 s of its states (1.2 s of robot time) at one pose.
        wait_for(lambda: service.robot("r1").last_seen >= held.last_seen + 0.3, 20, "more states")
        assert service.robot("r1").pose == held.pose
        assert service.task(task.id).status == TaskStatus.CANCELLED


def test_robot_killed_mid_task_fails_the_task(router_endpoint: str, tmp_path: Path) -> None:
    settings = load_settings(connect=[router_endpoint], task_timeout_s=60.0)
    with (
        zenoh_fleet_service(settings, tmp_path / "var" / "parkfleet.db") as service,
        sim_robots(router_endpoint, tmp_path, [("r1", 0.0, 0.0, 0.0)]) as proc,
    ):
        wait_for(lambda: len(service.robots()) == 1, 20, "the robot")
        task = service.submit(TaskRequest(goal=Pose(x=-8.0, y=8.0, theta=0.0)))
        wait_for(lambda: status_of(service, task) == TaskStatus.DRIVING, 20, "driving")
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        wait_for(lambda: status_of(service, task).final, 20, "the task to fail")
        failed = service.task(task.id)
        assert failed.status == TaskStatus.FAILED
        assert "lost" in (failed.reason or "")
        assert service.robot("r1").status == RobotStatus.LOST


def test_robot_killed_mid_task_requeues_to_another(router_endpoint: str, tmp_path: Path) -> None:
    settings = load_settings(
        connect=[router_endpoint], task_timeout_s=60.0, on_robot_lost="requeue"
    )
    with zenoh_fleet_service(settings, tmp_path / "var" / "parkfleet.db") as service:
        with sim_robots(router_endpoint, tmp_path, [("r1", 0.0, 0.0, 0.0)]) as first:
            wait_for(lambda: len(service.robots()) == 1, 20, "the first robot")
            task = service.submit(TaskRequest(goal=Pose(x=-6.0, y=6.0, theta=0.0)))
            wait_for(lambda: status_of(service, task) == TaskStatus.DRIVING, 20, "driving")
            first.send_signal(signal.SIGKILL)
            first.wait(timeout=10)
            wait_for(lambda: status_of(service, task) == TaskStatus.QUEUED, 20, "requeue")
        (tmp_path / "second").mkdir()
        with sim_robots(router_endpoint, tmp_path / "second", [("r2", 5.0, -5.0, 0.0)]):
            wait_for(lambda: status_of(service, task).final, 60, "the task to finish")
            done = service.task(task.id)
            assert done.status == TaskStatus.SUCCEEDED and done.robot_id == "r2"
            assert done.attempts == 2


def test_timeout_fails_the_task_and_holds_the_robot(router_endpoint: str, tmp_path: Path) -> None:
    settings = load_settings(connect=[router_endpoint], task_timeout_s=1.0)
    with (
        zenoh_fleet_service(settings, tmp_path / "var" / "parkfleet.db") as service,
        sim_robots(router_endpoint, tmp_path, [("r1", 0.0, 0.0, 0.0)]),
    ):
        wait_for(lambda: len(service.robots()) == 1, 20, "the robot")
        task = service.submit(TaskRequest(goal=Pose(x=-9.0, y=9.0, theta=3.0)))
        wait_for(lambda: status_of(service, task).final, 30, "the timeout")
        failed = service.task(task.id)
        assert failed.status == TaskStatus.FAILED
        assert "timeout" in (failed.reason or "")
        wait_for(lambda: service.robot("r1").status == RobotStatus.HOLDING, 20, "the robot to hold")


def test_bus_drops_bad_payloads_and_answers_obstacle_queries(
    router_endpoint: str, tmp_path: Path
) -> None:
    settings = load_settings(connect=[router_endpoint])
    keys = Keys(settings.fleet_name)
    with (
        zenoh_fleet_service(settings, tmp_path / "var" / "parkfleet.db") as service,
        open_session(settings, "client") as other,
    ):
        service.set_obstacles([Obstacle(x=1.0, y=2.0, radius=0.5)])
        state = RobotState(robot_id="r9", seq=1, stamp=0.0, pose=Pose(x=0.0, y=0.0))

        def published() -> bool:
            other.put(keys.state("r9"), b"{not json")
            other.put(keys.state("r8"), encode(state))  # key and payload disagree
            counters = service.counters
            return (
                counters.get("bus_dropped_invalid", 0) > 0
                and counters.get("bus_state_key_mismatch", 0) > 0
            )

        wait_for(published, 20, "bad payloads to be counted")
        assert service.robots() == []

        replies = list(other.get(keys.obstacles))
        sets = [
            ObstacleSet.model_validate_json(r.ok.payload.to_bytes())
            for r in replies
            if r.ok is not None
        ]
        assert sets and sets[0].obstacles == [Obstacle(x=1.0, y=2.0, radius=0.5)]

        # The service's own liveliness token is visible to robots.
        tokens = [str(r.ok.key_expr) for r in other.liveliness().get(keys.all_alive) if r.ok]
        assert keys.service_alive in tokens
