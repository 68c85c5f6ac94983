"""What the service's transitions ask of the world: effects, returned as plain data.

The ledger (:mod:`fleet.service.ledger`) changes in-memory state and *returns* these; the
shell queues them under its lock and the outbox (:mod:`fleet.service.outbox`) applies them
after the lock is released, stored before announced:

* :class:`StoreWrite` -- save a task version and its history event (durable on return);
* :class:`Publish` -- an assignment, a cancel, the obstacle set or an operator's control
  command on the bus;
* :class:`Notify` -- an event for the listeners (SSE clients, benches);
* :class:`PurgeFinished` -- delete finished tasks older than a wall-clock time (retention);
* :class:`SaveState` -- replace a state document of the service (operator holds, robots out
  of service), so it survives a restart.
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.core.tasks import FleetEvent, Task
from fleet.core.wire import CancelAssignment, ControlCommand, ObstacleSet, ParkAssignment


@dataclass(frozen=True, slots=True)
class StoreWrite:
    task: Task
    event: str  # history event name, e.g. "assigned"


@dataclass(frozen=True, slots=True)
class Publish:
    message: ParkAssignment | CancelAssignment | ObstacleSet | ControlCommand


@dataclass(frozen=True, slots=True)
class Notify:
    event: FleetEvent


@dataclass(frozen=True, slots=True)
class PurgeFinished:
    before: float  # [s since epoch]: finished tasks last updated before this go
    limit: int  # at most this many per call (bounded transactions)


@dataclass(frozen=True, slots=True)
class SaveState:
    key: str
    value: str  # JSON


Effect = StoreWrite | Publish | Notify | PurgeFinished | SaveState
Effects = list[Effect]
