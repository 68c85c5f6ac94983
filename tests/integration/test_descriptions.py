"""Robots describe themselves over real Zenoh; the service plans each with its own profile.

A mixed fleet on loopback: a TurtleBot-like robot (0.306 m/s) and a default one (1 m/s)
that describe themselves, and a robot of an older release that does not. The service runs
in this process with the real Zenoh bus and planner (recorded) and a SQLite store.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from support import wait_for

from fleet.core.params import RobotProfile
from fleet.core.planner import Plan, PlanningSnapshot, plan
from fleet.core.tasks import TaskRequest
from fleet.core.wire import Keys, Pose
from fleet.io.settings import Settings, load_settings
from fleet.io.transport import open_session
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from fleet.service.zenoh_bus import ZenohFleetBus
from robot_agent.agent import RobotAgent
from sim_agent.drive import SimDrive

pytestmark = pytest.mark.integration

TURTLEBOT = RobotProfile(wheel_radius=0.036, half_axle=0.117, max_wheel_speed=8.5, radius=0.17)


class RecordingPlanner:
    """The real planner, keeping every snapshot and plan (called on the planner thread)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.runs: list[tuple[PlanningSnapshot, Plan]] = []

    def __call__(self, snapshot: PlanningSnapshot) -> Plan:
        result = plan(snapshot)
        with self._lock:
            self.runs.append((snapshot, result))
        return result

    def arrivals(self) -> dict[str, float]:
        """Latest predicted arrival [s] per robot over the plans so far."""
        with self._lock:
            runs = list(self.runs)
        out: dict[str, float] = {}
        for _, p in runs:
            for d in p.decisions:
                if d.predicted_arrival_s is not None:
                    out[d.robot_id] = d.predicted_arrival_s
        return out


def agent(
    stack: ExitStack,
    session: Any,
    settings: Settings,
    robot_id: str,
    start: tuple[float, float, float],
    **kw: Any,
) -> RobotAgent:
    robot = RobotAgent(robot_id, SimDrive(start, settings.profile), session, settings, **kw)
    stack.callback(robot.close)
    return robot.start()


@pytest.fixture
def settings(router_endpoint: str) -> Settings:
    return load_settings(connect=[router_endpoint], task_timeout_s=120.0)


@pytest.fixture
def robot_session(settings: Settings) -> Iterator[Any]:
    with open_session(settings, "client") as session:
        yield session


def test_a_mixed_fleet_is_planned_with_each_robots_own_profile(
    settings: Settings, robot_session: Any, tmp_path: Path
) -> None:
    keys = Keys(settings.fleet_name)
    slow = settings.model_copy(update={"profile": TURTLEBOT, "robot_model": "TurtleBot 4"})
    planner = RecordingPlanner()
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    with ExitStack() as stack:
        stack.callback(store.close)
        # Up before the service: the service learns their descriptions by asking.
        tb4 = agent(stack, robot_session, slow, "tb4", (0.0, 0.0, 0.0))
        agent(stack, robot_session, settings, "old", (0.0, -4.0, 0.0), describe=False)
        session = stack.enter_context(open_session(settings, "client"))
        bus = ZenohFleetBus(session, keys)
        service = FleetService(settings, bus, store, planner=planner)
        stack.callback(service.close)
        service.start()
        # Up after the service: its description arrives as the put after its token.
        agent(stack, robot_session, settings, "std", (0.0, 4.0, 0.0))

        wait_for(lambda: len(service.robots()) == 3, 20, "three robots in the roster")
        wait_for(
            lambda: all(service.robot(r).described for r in ("tb4", "std")), 20, "descriptions"
        )
        assert tb4.description_queries >= 1
        seen = service.robot("tb4")
        assert seen.model == "TurtleBot 4" and seen.radius == pytest.approx(0.17)
        assert seen.max_speed == pytest.approx(0.306)
        assert service.robot("std").max_speed == pytest.approx(1.0)
        old = service.robot("old")
        assert not old.described and old.max_speed is None

        # A malformed description is dropped and counted, never reaches the roster.
        robot_session.put(keys.description("bogus"), b'{"kind": "description", "v": 1}')
        wait_for(
            lambda: any(k.startswith("dropped_") for k in bus.counters), 10, "the drop counted"
        )
        assert "bogus" not in {r.robot_id for r in service.robots()}

        for rid, y in (("tb4", 0.0), ("std", 4.0), ("old", -4.0)):
            service.submit(TaskRequest(goal=Pose(x=3.0, y=y), robot_id=rid))
        wait_for(lambda: set(planner.arrivals()) >= {"tb4", "std", "old"}, 30, "a plan")
        arrival = planner.arrivals()
        assert arrival["tb4"] > 2.5 * arrival["std"]  # 0.306 m/s against 1 m/s, same leg
        assert arrival["old"] < 1.5 * arrival["std"]  # planned with the host's 1 m/s
        snapshot = planner.runs[-1][0]
        profiles = {r.robot_id: r.profile for r in snapshot.robots}
        assert profiles["tb4"] == TURTLEBOT and profiles["old"] is None

        # Any query is answered (odd parameters and payload included) while the robot lives,
        # and none once it is closed (the queryable goes with the agent).
        def answers() -> list[Any]:
            got = robot_session.get(f"{keys.description('tb4')}?odd=1", payload=b"\xff", timeout=5)
            return [r.ok for r in got if r.ok is not None]

        assert len(answers()) == 1
        tb4.close()
        assert answers() == []
        assert tb4.callback_errors == 0
