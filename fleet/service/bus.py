"""The fleet service's I/O edge: what it publishes and how robot traffic reaches it.

Outgoing: :meth:`FleetBus.publish_assignment`, :meth:`FleetBus.publish_obstacles` and
:meth:`FleetBus.publish_control` (operator commands).
Incoming: the bus calls the :class:`FleetSink` given to :meth:`FleetBus.start` --
``on_state`` for every decoded ``RobotState``, ``on_robot_alive``/``on_robot_gone`` for
liveliness tokens appearing/disappearing, ``on_description`` for every decoded
``RobotDescription`` (put by the robot, or its answer to the bus's query), ``on_control``
for every operator command seen on the control keys (from any issuer, the service's own
included), ``obstacles()`` to answer late joiners, and ``last_states()`` to replay the robots
in a cell to a robot entering it (a dead robot publishes nothing it could hear).

:class:`MemoryBus` is the in-memory implementation for unit tests; the Zenoh one is
:class:`fleet.service.zenoh_bus.ZenohFleetBus`.
"""

from __future__ import annotations

import threading
from typing import Protocol

from fleet.core.wire import (
    CancelAssignment,
    ControlCommand,
    Obstacle,
    ObstacleSet,
    ParkAssignment,
    RobotDescription,
    RobotState,
)


class FleetSink(Protocol):
    """What a bus delivers to (implemented by :class:`fleet.service.fleet_service.FleetService`)."""

    def on_state(self, state: RobotState) -> None: ...

    def on_robot_alive(self, robot_id: str) -> None: ...

    def on_robot_gone(self, robot_id: str) -> None: ...

    def on_description(self, description: RobotDescription) -> None: ...

    def on_control(self, command: ControlCommand) -> None: ...

    def obstacles(self) -> list[Obstacle]: ...

    def last_states(self) -> list[tuple[RobotState, float]]: ...


class FleetBus(Protocol):
    """The service's connection to the robots."""

    def start(self, sink: FleetSink) -> None:
        """Begin delivering incoming traffic to ``sink``; a second call is ignored."""
        ...

    def publish_assignment(self, msg: ParkAssignment | CancelAssignment) -> None: ...

    def publish_obstacles(self, msg: ObstacleSet) -> None: ...

    def publish_control(self, msg: ControlCommand) -> None: ...

    @property
    def counters(self) -> dict[str, int]:
        """Dropped messages, callback errors etc."""
        ...

    def close(self) -> None:
        """Stop delivering; idempotent."""
        ...


class MemoryBus:
    """In-memory :class:`FleetBus`: records what is published; tests inject traffic."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.sink: FleetSink | None = None
        self.assignments: list[ParkAssignment | CancelAssignment] = []
        self.obstacle_sets: list[ObstacleSet] = []
        self.controls: list[ControlCommand] = []
        self.closed = False

    def start(self, sink: FleetSink) -> None:
        if self.sink is None:
            self.sink = sink

    def publish_assignment(self, msg: ParkAssignment | CancelAssignment) -> None:
        with self._lock:
            self.assignments.append(msg)

    def publish_obstacles(self, msg: ObstacleSet) -> None:
        with self._lock:
            self.obstacle_sets.append(msg)

    def publish_control(self, msg: ControlCommand) -> None:
        with self._lock:
            self.controls.append(msg)

    @property
    def counters(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        self.closed = True
        self.sink = None

    # -- test helpers: simulate robot traffic --------------------------------------------

    def _require_sink(self) -> FleetSink:
        if self.sink is None:
            raise RuntimeError("bus not started")
        return self.sink

    def deliver_state(self, state: RobotState) -> None:
        self._require_sink().on_state(state)

    def robot_alive(self, robot_id: str) -> None:
        self._require_sink().on_robot_alive(robot_id)

    def robot_gone(self, robot_id: str) -> None:
        self._require_sink().on_robot_gone(robot_id)

    def deliver_description(self, description: RobotDescription) -> None:
        self._require_sink().on_description(description)

    def deliver_control(self, command: ControlCommand) -> None:
        """An operator command from another tool (e.g. ``parkfleet estop``)."""
        self._require_sink().on_control(command)

    def sent(self, robot_id: str | None = None) -> list[ParkAssignment | CancelAssignment]:
        """Assignments published so far (to one robot, if given)."""
        with self._lock:
            return [m for m in self.assignments if robot_id is None or m.robot_id == robot_id]
