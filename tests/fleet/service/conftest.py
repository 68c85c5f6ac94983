"""Fixtures of the service tests: a service wired to the in-memory bus and store, a fake
clock, and helpers that play the robots."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from fleet.core.planner import Plan, PlanningSnapshot, TaskDecision
from fleet.core.tasks import FleetEvent, TaskEvent, TaskRequest, TaskStatus
from fleet.core.types import Law
from fleet.core.wire import CancelAssignment, ParkAssignment, Pose, RobotMode, RobotState
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.clock import FakeClock
from fleet.service.fleet_service import FleetService
from fleet.service.planner_worker import PlanFunction
from fleet.service.store import MemoryTaskStore, TaskStore

Decide = Callable[[PlanningSnapshot], list[TaskDecision]]


def assign_queued(law: Law = "cw", **kw: Any) -> Decide:
    """Each queued task to the first available robot it may take (the named one if any)."""

    def decide(snapshot: PlanningSnapshot) -> list[TaskDecision]:
        free = [r.robot_id for r in snapshot.robots if r.available]
        out = []
        for t in snapshot.tasks:
            if t.status is not TaskStatus.QUEUED:
                continue
            options = [r for r in free if t.named_robot in (None, r)]
            if options:
                free.remove(options[0])
                out.append(TaskDecision(t.task_id, options[0], "assign", law, **kw))
        return out

    return decide


class ScriptedPlanner:
    """A planner whose decisions come from ``decide``; it can be made to block."""

    def __init__(self, decide: Decide, safe: bool = True, notes: tuple[str, ...] = ()) -> None:
        self.decide = decide
        self.safe = safe
        self.notes = notes
        self.snapshots: list[PlanningSnapshot] = []
        self.gate: threading.Event | None = None  # when set up: wait for it before answering
        self.entered = threading.Event()

    def __call__(self, snapshot: PlanningSnapshot) -> Plan:
        self.snapshots.append(snapshot)
        self.entered.set()
        if self.gate is not None:
            assert self.gate.wait(30.0), "the test never released the planner"
        decisions = tuple(self.decide(snapshot))
        return Plan(snapshot.version, decisions, self.safe, 1.0, notes=self.notes)


class Fleet:
    """A service wired to a MemoryBus and a store, plus helpers that play the robots."""

    def __init__(
        self,
        store: TaskStore | None = None,
        planner: PlanFunction | None = None,
        **settings: Any,
    ) -> None:
        self.clock = FakeClock()
        self.bus = MemoryBus()
        self.store: TaskStore = store or MemoryTaskStore()
        self.settings = Settings(**settings)
        self.service = FleetService(
            self.settings, self.bus, self.store, clock=self.clock, planner=planner
        )
        self.events: list[FleetEvent] = []
        self.service.add_listener(self.events.append)
        self.seq = 0
        self.service.start(background=False)

    def robot(
        self,
        rid: str,
        x: float,
        y: float,
        theta: float = 0.0,
        mode: RobotMode = RobotMode.IDLE,
        task_id: str | None = None,
        revision: int = 0,
    ) -> None:
        self.seq += 1
        self.bus.deliver_state(
            RobotState(
                robot_id=rid,
                seq=self.seq,
                stamp=self.clock.wall(),
                pose=Pose(x=x, y=y, theta=theta),
                mode=mode,
                task_id=task_id,
                revision=revision,
            )
        )

    def join(self, rid: str, x: float, y: float) -> None:
        self.bus.robot_alive(rid)
        self.robot(rid, x, y)

    def parks(self, rid: str | None = None) -> list[ParkAssignment]:
        return [m for m in self.bus.sent(rid) if isinstance(m, ParkAssignment)]

    def cancels(self, rid: str | None = None) -> list[CancelAssignment]:
        return [m for m in self.bus.sent(rid) if isinstance(m, CancelAssignment)]

    def task_statuses(self, task_id: str) -> list[TaskStatus]:
        return [
            e.task.status for e in self.events if isinstance(e, TaskEvent) and e.task.id == task_id
        ]


@pytest.fixture
def fleet() -> Iterator[Fleet]:
    f = Fleet(task_timeout_s=30.0)
    yield f
    f.service.close()


def req(x: float, y: float, robot: str | None = None, **kw: Any) -> TaskRequest:
    return TaskRequest(goal=Pose(x=x, y=y, theta=0.0), robot_id=robot, **kw)
