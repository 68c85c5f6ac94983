"""Zenoh implementation of :class:`fleet.service.bus.FleetBus` (the service's I/O edge).

On :meth:`ZenohFleetBus.start` it declares

* a subscriber on ``robot/*/state`` -> ``sink.on_state``: the robots' fleet-rate stream
  (``Settings.fleet_rate_hz``, 10 Hz, and at once on a change of mode, task or faults),
  never their 50 Hz peer stream on the cell keys (fleet/core/wire.py, "State streams");
  compact states decode without pydantic, JSON ones (older robots, tools) as before; the
  key's robot id must match the payload's, else the sample is dropped;
* a liveliness subscriber on ``alive/*`` *with history* (robots already up are reported at
  once) -> ``sink.on_robot_alive`` / ``sink.on_robot_gone``; the service's own token is
  skipped;
* a subscriber on ``robot/*/description`` -> ``sink.on_description`` (the key's robot id
  must match the payload's); and when a robot appears (its token, or its first state) the
  bus asks for its description once with a non-blocking ``get`` on
  ``robot/<id>/description`` (the answer comes on a Zenoh thread, to the same handler). A
  robot of an older release never answers: the service plans it with its own profile.
  The bus forgets whom it asked when the robot's token goes, so a robot that comes back
  (maybe upgraded) is asked again; the set is bounded (``MAX_ASKED``);
* subscribers on the fleet's and every robot's ``control`` key -> ``sink.on_control`` (a
  robot's key must carry a command for that robot), so the service knows the e-stops and
  pauses other tools (``parkfleet estop``) latched;
* a queryable on ``obstacles`` answering late joiners with the current ``ObstacleSet``;
* a queryable on ``cell/**`` answering a robot that queries a cell with the last state of
  every robot whose last pose is there (``sink.last_states``), each on its cell key with
  its age as the attachment (fleet/core/wire.py, "Replay of last states"): a robot that
  died or was cut off is an obstacle to newcomers too;
* the service's liveliness token ``alive/_service``.

Malformed payloads are dropped and counted (``fleet.core.wire.Decoder``); exceptions raised by
the sink inside Zenoh callbacks are caught, logged and counted (Zenoh would print and
swallow them). The session belongs to the caller; :meth:`ZenohFleetBus.close` only
undeclares what the bus declared.
"""

from __future__ import annotations

import logging
import threading
from collections import Counter
from collections.abc import Callable
from typing import Any, TypeVar

import zenoh

from fleet.core.wire import (
    SERVICE_TOKEN,
    CancelAssignment,
    ControlCommand,
    Keys,
    ObstacleSet,
    ParkAssignment,
    RobotDescription,
    RobotState,
    encode,
    encode_age,
    encode_state,
)
from fleet.io.decoder import Decoder
from fleet.io.operator import put_control
from fleet.service.bus import FleetSink

_log = logging.getLogger(__name__)
#: Messages that name their robot, checked against the key they came on.
_Addressed = TypeVar("_Addressed", RobotState, RobotDescription, ControlCommand)
#: Robots asked for their description remembered at most (then the memory starts afresh:
#: at worst a robot is asked once more).
MAX_ASKED = 4096
#: [s] how long a description query waits for the robot's answer.
DESCRIPTION_QUERY_TIMEOUT_S = 5.0


class ZenohFleetBus:
    """:class:`fleet.service.bus.FleetBus` over a Zenoh session."""

    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self._session = session
        self._keys = keys
        self._decoder = Decoder("fleet-service")
        self._lock = threading.Lock()
        self._counters: Counter[str] = Counter()
        self._sink: FleetSink | None = None
        self._declared: list[Any] = []
        self._closed = False
        self._asked: set[str] = set()  # robots asked for their description (this token)

    # -- outgoing ------------------------------------------------------------------------

    def publish_assignment(self, msg: ParkAssignment | CancelAssignment) -> None:
        self._put(self._keys.assignment(msg.robot_id), encode(msg), "assignments_sent")

    def publish_obstacles(self, msg: ObstacleSet) -> None:
        self._put(self._keys.obstacles, encode(msg), "obstacle_sets_sent")

    def publish_control(self, msg: ControlCommand) -> None:
        """An operator command, never dropped (``fleet.io.operator.put_control``)."""
        with self._lock:
            if self._closed:
                return
        try:
            put_control(self._session, self._keys, msg)
        except zenoh.ZError:
            self._count("publish_errors")
            _log.exception("could not publish control command %s", msg.command.value)
            return
        self._count("controls_sent")

    def _put(self, key: str, payload: bytes, counter: str) -> None:
        with self._lock:
            if self._closed:
                return
        try:
            self._session.put(key, payload)
        except zenoh.ZError:
            self._count("publish_errors")
            _log.exception("could not publish on %s", key)
            return
        self._count(counter)

    # -- incoming ------------------------------------------------------------------------

    def start(self, sink: FleetSink) -> None:
        """Declare subscribers, queryable and token, delivering to ``sink``; once only."""
        with self._lock:
            if self._sink is not None or self._closed:
                return
            self._sink = sink
        session, keys = self._session, self._keys
        self._declared.append(
            session.declare_subscriber(keys.all_states, self._guard("state", self._on_state))
        )
        self._declared.append(
            session.liveliness().declare_subscriber(
                keys.all_alive, self._guard("liveliness", self._on_alive), history=True
            )
        )
        self._declared.append(
            session.declare_subscriber(
                keys.all_descriptions, self._guard("description", self._on_description)
            )
        )
        for key in (keys.control(), keys.all_robot_controls):
            self._declared.append(
                session.declare_subscriber(key, self._guard("control", self._on_control))
            )
        self._declared.append(
            session.declare_queryable(keys.obstacles, self._guard("query", self._on_query))
        )
        self._declared.append(
            session.declare_queryable(
                keys.all_peer_states, self._guard("replay", self._on_cell_query)
            )
        )
        self._declared.append(session.liveliness().declare_token(keys.service_alive))

    def _guard(self, what: str, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        def callback(arg: Any) -> None:
            try:
                fn(arg)
            except Exception:
                self._count(f"{what}_callback_errors")
                _log.exception("fleet bus: %s callback failed", what)

        return callback

    def _addressed(
        self, model: type[_Addressed], sample: zenoh.Sample, what: str
    ) -> _Addressed | None:
        """The decoded message if its robot is the key's (else dropped and counted as
        ``<what>_key_mismatch``; a malformed one is counted by the decoder)."""
        message = self._decoder.decode(model, sample.payload.to_bytes())
        if message is None:
            return None
        if self._keys.robot_of(str(sample.key_expr)) != message.robot_id:
            self._count(f"{what}_key_mismatch")
            return None
        return message

    def _on_state(self, sample: zenoh.Sample) -> None:
        sink = self._sink
        if sink is None:
            return
        state = self._addressed(RobotState, sample, "state")
        if state is None:
            return
        sink.on_state(state)
        self._ask_description(state.robot_id)

    def _on_description(self, sample: zenoh.Sample) -> None:
        sink = self._sink
        if sink is None:
            return
        description = self._addressed(RobotDescription, sample, "description")
        if description is None:
            return
        self._count("descriptions_received")
        sink.on_description(description)

    def _on_description_reply(self, reply: zenoh.Reply) -> None:
        if reply.ok is None:
            self._count("description_query_errors")
            return
        self._on_description(reply.ok)

    def _ask_description(self, robot_id: str) -> None:
        """Ask the robot for its description once (per token), without blocking."""
        with self._lock:
            if self._closed or robot_id in self._asked:
                return
            if len(self._asked) >= MAX_ASKED:
                self._asked.clear()
            self._asked.add(robot_id)
        try:
            self._session.get(
                self._keys.description(robot_id),
                self._guard("description", self._on_description_reply),
                timeout=DESCRIPTION_QUERY_TIMEOUT_S,
            )
        except zenoh.ZError:
            self._count("description_query_errors")
            _log.exception("could not ask %s for its description", robot_id)
            return
        self._count("description_queries")

    def _on_control(self, sample: zenoh.Sample) -> None:
        sink = self._sink
        if sink is None:
            return
        command = self._addressed(ControlCommand, sample, "control")
        if command is None:
            return
        sink.on_control(command)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        sink = self._sink
        robot_id = self._keys.robot_of(str(sample.key_expr))
        if sink is None or robot_id is None or robot_id == SERVICE_TOKEN:
            return
        if sample.kind == zenoh.SampleKind.DELETE:
            with self._lock:
                self._asked.discard(robot_id)
            sink.on_robot_gone(robot_id)
        else:
            sink.on_robot_alive(robot_id)
            self._ask_description(robot_id)

    def _on_query(self, query: zenoh.Query) -> None:
        sink = self._sink
        if sink is None:
            return
        msg = ObstacleSet(obstacles=sink.obstacles())
        query.reply(self._keys.obstacles, encode(msg))
        self._count("obstacle_queries")

    def _on_cell_query(self, query: zenoh.Query) -> None:
        sink = self._sink
        if sink is None:
            return
        keys = self._keys
        for state, age in sink.last_states():
            key = keys.peer_state(state.robot_id, keys.cell(state.pose.x, state.pose.y))
            if query.key_expr.intersects(zenoh.KeyExpr(key)):
                query.reply(key, encode_state(state), attachment=encode_age(age))
                self._count("peer_replays")

    def _count(self, key: str) -> None:
        with self._lock:
            self._counters[key] += 1

    @property
    def counters(self) -> dict[str, int]:
        with self._lock:
            out = dict(self._counters)
        for reason, n in self._decoder.dropped.items():
            out[f"dropped_{reason}"] = n
        return out

    def close(self) -> None:
        """Undeclare everything the bus declared; idempotent. The session stays open."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            declared, self._declared = self._declared, []
            self._sink = None
        for entity in reversed(declared):
            try:
                entity.undeclare()
            except zenoh.ZError:
                _log.debug("undeclare failed (session closed?)", exc_info=True)
