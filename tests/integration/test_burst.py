"""A burst of 1 000 tasks while robots come and go: every accepted task ends final.

Real Zenoh router, the fleet service in this process with a real SQLite file, and two
``parkfleet sim`` processes: the first is SIGKILLed in the middle of the burst (its tasks
are requeued), the second joins later. Short task timeouts keep the run bounded: the
point is that nothing accepted is lost or left hanging, not that every robot arrives.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
from pathlib import Path

import pytest
from support import wait_for

from fleet.core.tasks import GoalRejected, TaskRequest, TaskStatus
from fleet.core.wire import Keys, Pose
from fleet.io.processes import sim_command, terminate
from fleet.io.settings import load_settings
from fleet.io.transport import open_session
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from fleet.service.zenoh_bus import ZenohFleetBus

pytestmark = pytest.mark.integration

TASKS = 1000
FINAL = {s.value for s in TaskStatus if s.final}


ROBOTS = 10  # per sim process


def _spawn_file(path: Path, prefix: str, row: float) -> Path:
    """Robots spread among the goals, half a grid step off every goal (1.06 m from it)."""
    robots = [
        {"id": f"{prefix}{i}", "x": -27.75 + 6.0 * i, "y": row, "theta": 0.0} for i in range(ROBOTS)
    ]
    path.write_text(json.dumps(robots))
    return path


def _under_way(service: FleetService, prefix: str) -> int:
    """Tasks being driven right now by robots whose id starts with ``prefix``."""
    return sum(
        1
        for t in service.tasks(status=TaskStatus.DRIVING)
        if t.robot_id is not None and t.robot_id.startswith(prefix)
    )


# Its own waits bound it (420 s to drain); the suite-wide 300 s would cut it short on a busy
# machine, where the service's one-by-one durable writes of ~3 000 transitions are the pace.
@pytest.mark.timeout(600)
def test_every_accepted_task_of_a_burst_ends_final_while_robots_come_and_go(
    router_endpoint: str, tmp_path: Path
) -> None:
    settings = load_settings(
        connect=[router_endpoint],
        yard=(-40.0, 40.0, -40.0, 40.0),
        task_timeout_s=1.0,
        on_robot_lost="requeue",
    )
    goals = [
        Pose(x=-30.0 + 1.5 * (k % 40), y=-30.0 + 1.5 * (k // 40), theta=0.0) for k in range(TASKS)
    ]
    first = second = None
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    with open_session(settings, "client") as session:
        service = FleetService(settings, ZenohFleetBus(session, Keys()), store)
        service.start()
        try:
            first = subprocess.Popen(
                sim_command(
                    router_endpoint,
                    ROBOTS,
                    time_scale=10.0,
                    spawn=str(_spawn_file(tmp_path / "a.json", "a", -20.25)),
                ),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            wait_for(lambda: len(service.robots()) == ROBOTS, 30, "the first robots")

            accepted: list[str] = []
            rejected = 0
            for k, goal in enumerate(goals):
                try:
                    accepted.append(service.submit(TaskRequest(goal=goal, direction="cw")).id)
                except GoalRejected:
                    rejected += 1  # refused with a reason: never accepted, so never stored
                if k == TASKS // 2:
                    # Robots go while they drive tasks of the burst ...
                    wait_for(lambda: _under_way(service, "a") >= 3, 60, "three tasks driven")
                    first.kill()
                    first.wait(10)
                    second = subprocess.Popen(  # ... and others come
                        sim_command(
                            router_endpoint,
                            ROBOTS,
                            time_scale=10.0,
                            spawn=str(_spawn_file(tmp_path / "b.json", "b", -5.25)),
                        ),
                        stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL,
                    )
            assert len(accepted) == TASKS - rejected and len(accepted) > 0.9 * TASKS

            def all_final() -> bool:
                return all(t.status.final for t in service.tasks())

            # Bounded: 1 s timeouts over 10 robots drain 1 000 tasks in about two minutes at worst.
            wait_for(all_final, 420, "every task to end", poll=0.5)
            # The killed robots' tasks were requeued and assigned again (on_robot_lost).
            assert any(t.attempts > 1 for t in service.tasks()), "no task was requeued"
        finally:
            service.close()
            for proc in (first, second):
                if proc is not None:
                    terminate(proc)
    store.close()

    # What the store holds is what was accepted: once each, every one final.
    with sqlite3.connect(tmp_path / "parkfleet.db") as db:
        tables = {row[0] for row in db.execute("select name from sqlite_master where type='table'")}
        assert "tasks" in tables
        rows = db.execute("select id from tasks").fetchall()
    assert sorted(r[0] for r in rows) == sorted(accepted)
    reopened = SqliteTaskStore(tmp_path / "parkfleet.db")
    try:
        assert {t.status.value for t in reopened.list()} <= FINAL
        assert len(reopened.list()) == len(accepted)
    finally:
        reopened.close()
