"""Stored before announced, and never a store write or a publish under the service lock.

A store and a bus that check, on every write and publish, that the calling thread does not
hold the service lock, and that record the order of what happens to each task: its store
write, then its publish, then its event. Run through a whole life cycle (assign, acknowledge,
arrive, cancel, timeout, robot lost, obstacles) on one thread and with the service's threads.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest
from support import wait_for

from fleet.core.tasks import FleetEvent, Task, TaskEvent, TaskStatus
from fleet.core.wire import (
    CancelAssignment,
    ObstacleSet,
    ParkAssignment,
    Pose,
    RobotMode,
    RobotState,
)
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.clock import FakeClock
from fleet.service.fleet_service import RESEND_INTERVAL_S, FleetService
from fleet.service.store import MemoryTaskStore
from tests.fleet.service.conftest import req


class Journal:
    """What happened, in order, and a check that the service lock is free meanwhile."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.entries: list[tuple[str, str, str]] = []  # (what, task id, detail)
        self.service: FleetService | None = None
        self.violations: list[str] = []

    def lock_free(self, what: str) -> None:
        service = self.service
        if service is not None and service._lock._is_owned():  # type: ignore[attr-defined]
            self.violations.append(f"{what} under the service lock")

    def add(self, what: str, task_id: str, detail: str) -> None:
        with self.lock:
            self.entries.append((what, task_id, detail))

    def of(self, task_id: str) -> list[tuple[str, str]]:
        with self.lock:
            return [(w, d) for w, t, d in self.entries if t == task_id]


class CheckedStore(MemoryTaskStore):
    def __init__(self, journal: Journal) -> None:
        super().__init__()
        self.journal = journal

    def save(self, task: Task, event: str) -> None:
        self.journal.lock_free("store write")
        super().save(task, event)
        self.journal.add("stored", task.id, f"{task.status.value}/{task.revision}")

    def save_new(self, task: Task, idempotency_key: str | None) -> Task:
        self.journal.lock_free("store write")
        stored = super().save_new(task, idempotency_key)
        self.journal.add("stored", task.id, f"{task.status.value}/{task.revision}")
        return stored


class CheckedBus(MemoryBus):
    def __init__(self, journal: Journal, store: CheckedStore) -> None:
        super().__init__()
        self.journal = journal
        self.store = store

    def publish_assignment(self, msg: ParkAssignment | CancelAssignment) -> None:
        self.journal.lock_free("publish")
        stored = self.store.get(msg.task_id)
        if isinstance(msg, ParkAssignment):  # the revision sent is the one stored
            if stored is None or stored.revision != msg.revision or not stored.status.under_way:
                self.journal.violations.append(f"park {msg.task_id} sent before stored")
        elif stored is None or not stored.status.final:
            self.journal.violations.append(f"cancel {msg.task_id} sent before stored")
        super().publish_assignment(msg)
        self.journal.add("published", msg.task_id, f"{msg.kind}/{getattr(msg, 'revision', '-')}")

    def publish_obstacles(self, msg: ObstacleSet) -> None:
        self.journal.lock_free("publish")
        super().publish_obstacles(msg)


class Checked:
    """A service on the checked store and bus (threads or not), its clock and its journal."""

    def __init__(self, background: bool, **settings: Any) -> None:
        self.journal = Journal()
        self.store = CheckedStore(self.journal)
        self.bus = CheckedBus(self.journal, self.store)
        self.clock = FakeClock()
        self.service = FleetService(Settings(**settings), self.bus, self.store, clock=self.clock)
        self.journal.service = self.service
        self.service.add_listener(self.on_event)
        self.service.start(background=background)
        self.background = background
        self.seq = 0

    def on_event(self, event: FleetEvent) -> None:
        self.journal.lock_free("listener call")
        if isinstance(event, TaskEvent):
            if self.store.get(event.task.id) != event.task:
                self.journal.violations.append(f"{event.task.id} announced before stored")
            self.journal.add("notified", event.task.id, event.task.status.value)

    def state(self, rid: str, x: float, mode: RobotMode, task_id: str | None = None) -> None:
        self.seq += 1
        self.bus.deliver_state(
            RobotState(
                robot_id=rid,
                seq=self.seq,
                stamp=0.0,
                pose=Pose(x=x, y=0.0),
                mode=mode,
                task_id=task_id,
            )
        )

    def tick(self) -> None:
        if not self.background:
            self.service.tick()

    def until(self, predicate: Any, what: str) -> None:
        """Wait for the service threads (or tick once, without them)."""
        if not self.background:
            self.service.tick()
        wait_for(predicate, 20, what)

    def status(self, task_id: str) -> TaskStatus:
        return self.service.task(task_id).status


@pytest.fixture(params=[False, True], ids=["one-thread", "threads"])
def checked(request: pytest.FixtureRequest) -> Iterator[Checked]:
    c = Checked(background=request.param, task_timeout_s=30.0, on_robot_lost="fail")
    yield c
    c.service.close()
    assert c.journal.violations == []
    assert c.service.counters.get("listener_errors", 0) == 0


def test_every_transition_is_stored_then_published_then_announced(checked: Checked) -> None:
    c = checked
    c.bus.robot_alive("r1")
    c.state("r1", 0.0, RobotMode.IDLE)
    task = c.service.submit(req(3.0, 0.0, direction="cw"))
    c.until(lambda: c.status(task.id) is TaskStatus.ASSIGNED, "the assignment")
    wait_for(lambda: len(c.bus.sent("r1")) == 1, 20, "the park message")
    c.state("r1", 0.5, RobotMode.DRIVING, task.id)
    c.until(lambda: c.status(task.id) is TaskStatus.DRIVING, "the acknowledgement")
    c.state("r1", 3.0, RobotMode.ARRIVED, task.id)
    c.until(lambda: c.status(task.id) is TaskStatus.SUCCEEDED, "the arrival")
    wait_for(lambda: ("notified", "succeeded") in c.journal.of(task.id), 20, "the last event")
    assert c.journal.of(task.id) == [
        ("stored", "queued/0"),
        ("notified", "queued"),
        ("stored", "assigned/0"),
        ("published", "park/0"),
        ("notified", "assigned"),
        ("stored", "driving/0"),
        ("notified", "driving"),
        ("stored", "succeeded/0"),
        ("notified", "succeeded"),
    ]

    # Cancel answers once stored; its stop is published after, then announced.
    c.state("r1", 3.0, RobotMode.IDLE)
    second = c.service.submit(req(-3.0, 0.0, direction="cw"))
    c.until(lambda: c.status(second.id) is TaskStatus.ASSIGNED, "the second assignment")
    cancelled = c.service.cancel(second.id)
    assert c.store.get(second.id) == cancelled  # stored when cancel returns
    wait_for(lambda: ("notified", "cancelled") in c.journal.of(second.id), 20, "cancel event")
    assert c.journal.of(second.id)[-3:] == [
        ("stored", "cancelled/0"),
        ("published", "cancel/-"),
        ("notified", "cancelled"),
    ]

    # A timeout's stop, a lost robot, a re-send and the obstacles take the same road.
    third = c.service.submit(req(-6.0, 0.0, direction="cw"))
    c.until(lambda: c.status(third.id) is TaskStatus.ASSIGNED, "the third assignment")
    c.clock.advance(RESEND_INTERVAL_S)
    c.until(lambda: len(c.bus.sent("r1")) >= 4, "a re-send")
    c.clock.advance(31.0)
    c.until(lambda: c.status(third.id) is TaskStatus.FAILED, "the timeout")
    wait_for(lambda: ("notified", "failed") in c.journal.of(third.id), 20, "timeout event")
    assert c.journal.of(third.id)[-3:] == [
        ("stored", "failed/0"),
        ("published", "cancel/-"),
        ("notified", "failed"),
    ]
    c.service.set_obstacles([])
    c.bus.robot_alive("r2")
    c.state("r2", 6.0, RobotMode.IDLE)
    fourth = c.service.submit(req(6.0, 3.0, robot="r2", direction="cw"))
    c.until(lambda: c.status(fourth.id) is TaskStatus.ASSIGNED, "the fourth assignment")
    c.bus.robot_gone("r2")
    c.until(lambda: c.status(fourth.id) is TaskStatus.FAILED, "the lost robot's task")
    wait_for(lambda: ("notified", "failed") in c.journal.of(fourth.id), 20, "its event")
    assert c.journal.of(fourth.id)[-2:] == [("stored", "failed/0"), ("notified", "failed")]
