"""Wire contract: Zenoh key expressions and the JSON messages carried on them.

Pure module (no Zenoh, no logging): builds keys, validates ids, encodes and parses messages.
Every message carries the schema version ``v``. Parsing never raises: a malformed, oversized
or unknown payload comes back as a :class:`Rejected` with the reason; the I/O edge
(:class:`fleet.io.decoder.Decoder`) drops, logs and counts it.

Key expressions::

    parkfleet/<fleet>/robot/<id>/state        robot -> fleet   RobotState, fleet rate (10 Hz)
    parkfleet/<fleet>/cell/<cx>/<cy>/<id>     robot -> peers   RobotState, control rate (50 Hz)
    parkfleet/<fleet>/robot/<id>/description  robot -> fleet   RobotDescription (also a queryable)
    parkfleet/<fleet>/robot/<id>/assignment   fleet -> robot   ParkAssignment | CancelAssignment
    parkfleet/<fleet>/robot/<id>/control      operator -> robot ControlCommand for that robot
    parkfleet/<fleet>/control                 operator -> all  ControlCommand for every robot
    parkfleet/<fleet>/obstacles               fleet -> all     ObstacleSet (also a queryable)
    parkfleet/<fleet>/alive/<id>              liveliness token of each robot
    parkfleet/<fleet>/alive/_service          liveliness token of the fleet service

State streams and their encoding (the hot messages):

* **Peer stream** ``cell/<cx>/<cy>/<id>``: a robot publishes every control tick under the
  grid cell it stands in, ``(cx, cy) = (floor(x / c), floor(y / c))`` of its world-frame
  position [m], with the fleet's cell size ``c`` [m] (``Settings.peer_cell_m``, by default
  twice the peer radius of Eq. (27)). A robot subscribes to the cells that meet the square
  of half-width ``c`` around itself (:func:`cells_around`: the 3 x 3 block), and
  re-subscribes when it enters another cell: every peer within ``c`` of it -- the peer
  radius plus as much again for motion between re-subscriptions -- is on one of its
  subscribed keys, also at cell borders. Tools and the service may subscribe to
  ``cell/**`` (:attr:`Keys.all_peer_states`) to see everything. Every robot of a fleet
  must use the same cell size (set it in the fleet's shared settings).
* **Replay of last states**: a robot that subscribes to a cell also queries it
  (``get`` on ``cell/<cx>/<cy>/*``); the fleet service answers with the last state of every
  robot whose last pose lies in that cell (a dead or cut-off robot publishes nothing a
  newcomer could hear -- also one that fell silent a moment ago, so every robot is
  replayed, not only those silent a while), on that robot's cell key, with the attachment
  :func:`encode_age` (how long ago the service heard it [s]). The receiver takes the state
  as heard that long ago and keeps the newest by ``seq``: a live robot's stream wins.
  Compatibility: an older service does not answer and an older robot does not ask;
  nothing else changes.
* **Fleet-rate stream** ``robot/<id>/state`` (the key the service and tools always read):
  the same message at the fleet rate (``Settings.fleet_rate_hz``, default 10 Hz), and at
  once whenever the robot's mode, task, revision, detail or faults change, so
  acknowledgements and e-stop confirmations are not delayed by the lower rate.
* **Compact encoding** of ``RobotState`` (:func:`encode_state`, :func:`parse_state`): one
  version byte ``0x01`` then a MessagePack array of the fields in a fixed order
  (:class:`StateFrame`), decoded and validated by msgspec without pydantic. Compatibility
  rule: a receiver of this release accepts both encodings on every state key (a first
  byte ``{`` or JSON whitespace is the JSON of before, validated by pydantic); a first byte
  below ``0x20`` other than ``0x01`` is a compact version it does not know and is
  rejected (``version``), a malformed payload ``invalid``, both dropped and counted.
  Fields are only ever appended (with defaults); a receiver ignores trailing fields it
  does not know, so additive changes keep ``0x01``; a breaking one takes the next byte.
  :func:`as_json` turns any payload into its JSON for tools (``parkfleet`` prints JSON).
  A receiver of an older release understands only JSON and never subscribes to cell
  keys: upgrade the service before the robots, or set ``Settings.state_encoding = "json"``
  on robots talking to an older service. An older robot publishes its 50 Hz JSON on
  ``robot/<id>/state`` only and subscribes to ``robot/*/state``: it sees upgraded robots
  at the fleet rate, and upgraded robots do not see it on their cells -- upgrade a
  fleet's robots together.

Prediction (``RobotState.ahead``, :class:`Ahead`; docs/safety.md "Latency where it lives"):
a robot tells its peers where it predicts itself when the command of the state acts --
the posture, that instant as a lead over the state's send, a radius and a heading error
around it, and how fast it may move under its commands in flight -- and its peers'
safety filters see it there. Compatibility rule: one additive field, ``v`` stays 1; in the
compact layout it is appended as the last element (``0x01`` kept), in JSON an optional key.
An older receiver ignores it (an unknown key, a trailing element); a state without it (an
older robot, or a robot that could not sense this tick) is seen around its measured pose
with the spread of before (``SafetyConfig.peer_spread``).

Protocol between the fleet service and a robot agent:

* A robot publishes ``RobotState`` at its control rate; ``task_id`` names the task it is
  executing (or last executed). A state carrying an assignment's ``task_id`` acknowledges
  it; the service re-sends an assignment until it sees that acknowledgement.
* ``ParkAssignment`` with a new ``task_id`` replaces whatever the robot was doing; a repeat
  of the current ``task_id`` with the same or a lower ``revision`` is ignored (delivery is
  at-least-once, and a late duplicate of an older revision must not undo a newer one).
* ``revision`` (>= 0, starting at 0): the fleet re-planned the task. A higher revision of
  the current ``task_id`` replaces its law, gains, tolerance, limits and avoidance while the
  robot keeps driving from where it is (an arrived or cancelled task stays so). The robot
  reports the revision it runs (``RobotState.revision``); a state with the task id and at
  least that revision acknowledges it, and the service re-sends the revision until then.
* On arrival within tolerance the robot stops and reports ``mode=arrived`` with the task id;
  the service marks the task succeeded.
* ``start_delay_s`` (>= 0): after applying an assignment (or a revision) the robot stands
  still for that long of its own time, ``mode=waiting``, then drives (a planned wait for a
  peer to pass). ``hold``: the robot stands still, ``mode=waiting``, until a higher revision
  releases it (the fleet found no safe option yet).
* ``route`` (via-points) and ``pass_m``: the robot passes the via-points
  in order without stopping, then parks at ``goal`` (:class:`ParkAssignment` has the
  rule and its compatibility).
* ``CancelAssignment`` for the current task stops the robot: ``mode=holding``, task id kept.
* With no assignment the robot stands still in ``mode=idle`` with ``task_id=None``.

Robot description (:class:`RobotDescription`, the role of VDA 5050's factsheet): what the
robot is -- body radius, axle, wheel radius and limit, whether it may reverse. A robot
puts it on ``robot/<id>/description`` when it declares its liveliness token and answers
queries on that key for as long as the token lives; the fleet plans, checks goals and
draws each robot with its own description. Compatibility rule: a new key and a new
message, nothing else changes (``v`` stays 1). A robot of an older release publishes no
description: the fleet then plans it with the host's own ``[profile]`` and says so
(the robot is listed as ``described: false``). A service of an older release never
subscribes to the key and behaves as before.

Operator control (:class:`ControlCommand`, VDA 5050's ``startPause``/``stopPause`` and its
emergency stop), obeyed by every agent directly, so any tool can stop the fleet even when
the fleet service is down:

* ``pause`` -> the robot stops and keeps its task (``mode=paused``); ``resume`` -> it drives
  on from where it stands (the service re-plans it as a new revision).
* ``estop`` -> wheels to zero at the next control tick, the task kept, ``mode=estop``,
  latched until ``release``; ``release`` clears the latch only (a robot also paused stays
  paused until ``resume``). Pause and e-stop are independent latches; e-stop wins.
* ``robot_id`` absent (on the fleet key) = every robot; on a robot's key it must name it.
* ``seq`` orders the commands of one ``issuer``: a robot applies a command only if its
  ``seq`` is above the last one it applied from that issuer, so repeats (send a command a
  few times: delivery is best effort) and reordered copies are harmless. One-shot tools use
  the wall clock in microseconds as ``seq``.
Fencing term (:class:`TermFence`, high availability on PostgreSQL, docs/deployment.md "Standby and
fencing"). Compatibility rule: one additive field, ``v`` stays 1.

* ``term`` (>= 0) on ``ParkAssignment``, ``CancelAssignment`` and ``ControlCommand``: the
  leadership term of the fleet service that sent it; each new leader's term is one above the
  last (kept in the database). **Absent = 0**: a service without a leader election (the
  SQLite default, or an older release) sends term 0.
* A robot remembers the highest term it has seen on assignments, cancels and the service's
  control commands, and **drops (and counts) any of those with a lower term**: a deposed
  leader can no longer command a robot that has heard its successor. A higher term raises the
  highest; an equal one is obeyed as before (revision and ``seq`` rules unchanged).
* ``ControlCommand`` with term 0 (``parkfleet estop`` and other operator tools) is **always
  obeyed** (an emergency stop must never be fenced off); it does not raise the highest.
* The highest term lives in the agent's memory: a restarted agent obeys the first leader it
  hears. A robot that saw term N ignores a term-0 service until its agent restarts (do not
  switch a running fleet from PostgreSQL back to SQLite without restarting the agents).
* An older robot ignores the field (unknown fields are ignored): it is not fenced.

* A robot says why it does not move: ``mode`` plus ``RobotState.detail`` (e.g. ``holding``
  with ``pose stale``), and its active faults in ``RobotState.errors`` (code, level,
  message, since).
"""

from __future__ import annotations

import math
import re
from collections import OrderedDict
from dataclasses import dataclass
from enum import StrEnum
from typing import Annotated, Any, Literal, TypeVar

import msgspec
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    TypeAdapter,
    ValidationError,
    field_serializer,
    field_validator,
    model_validator,
)

from fleet.core.geometry import segment_distance
from fleet.core.params import Avoidance, Gains, RobotProfile, Tolerance
from fleet.core.types import Law

SCHEMA_VERSION = 1
MAX_PAYLOAD_BYTES = 64 * 1024
SERVICE_TOKEN = "_service"
#: [m] default grid cell of the peer stream: twice the default peer radius of Eq. (27).
DEFAULT_CELL_M = 2.0

_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


def validate_id(value: str, what: str = "robot id") -> str:
    """Return ``value`` if it is a safe key-expression chunk, else raise ValueError.

    1-64 characters from ``[A-Za-z0-9_.-]``, starting with a letter or digit: no
    ``/ * $ ? #`` wildcards or separators, never empty, never the service token.
    """
    if not isinstance(value, str) or not _ID_RE.fullmatch(value):
        raise ValueError(
            f"invalid {what} {value!r}: use 1-64 characters from A-Z a-z 0-9 _ . -, "
            "starting with a letter or digit"
        )
    return value


RobotId = Annotated[str, Field(pattern=_ID_RE.pattern)]


Cell = tuple[int, int]


def cell_of(x: float, y: float, cell_m: float) -> Cell:
    """Grid cell ``(floor(x / cell_m), floor(y / cell_m))`` of a world-frame position [m]."""
    return (math.floor(x / cell_m), math.floor(y / cell_m))


def cells_around(x: float, y: float, reach_m: float, cell_m: float) -> frozenset[Cell]:
    """Every cell meeting the square of half-width ``reach_m`` [m] around (x, y) [m]: a
    robot there sees, on these cells, every peer within ``reach_m`` (borders included)."""
    x0, y0 = cell_of(x - reach_m, y - reach_m, cell_m)
    x1, y1 = cell_of(x + reach_m, y + reach_m, cell_m)
    return frozenset((cx, cy) for cx in range(x0, x1 + 1) for cy in range(y0, y1 + 1))


class Keys:
    """Key expressions of one fleet (``parkfleet/<fleet>/...``); ``cell_m`` [m] is the
    fleet's grid cell of the peer stream (module docstring)."""

    def __init__(self, fleet: str = "default", cell_m: float = DEFAULT_CELL_M) -> None:
        self.fleet = validate_id(fleet, "fleet name")
        self.root = f"parkfleet/{self.fleet}"
        if not (math.isfinite(cell_m) and cell_m > 0):
            raise ValueError(f"cell size must be a positive number of metres, got {cell_m}")
        self.cell_m = float(cell_m)

    def state(self, robot_id: str) -> str:
        """A robot's fleet-rate state (read by the service and tools)."""
        return f"{self.root}/robot/{validate_id(robot_id)}/state"

    def cell(self, x: float, y: float) -> Cell:
        """The cell of a world-frame position [m] (:func:`cell_of` with this fleet's size)."""
        return cell_of(x, y, self.cell_m)

    def peer_state(self, robot_id: str, cell: Cell) -> str:
        """A robot's control-rate state, published under the cell it stands in."""
        return f"{self.root}/cell/{cell[0]}/{cell[1]}/{validate_id(robot_id)}"

    def cell_states(self, cell: Cell) -> str:
        """Every robot's control-rate state in one cell."""
        return f"{self.root}/cell/{cell[0]}/{cell[1]}/*"

    @property
    def all_peer_states(self) -> str:
        """Every robot's control-rate state, in every cell (tools)."""
        return f"{self.root}/cell/*/*/*"

    def description(self, robot_id: str) -> str:
        return f"{self.root}/robot/{validate_id(robot_id)}/description"

    @property
    def all_descriptions(self) -> str:
        return f"{self.root}/robot/*/description"

    def assignment(self, robot_id: str) -> str:
        return f"{self.root}/robot/{validate_id(robot_id)}/assignment"

    def control(self, robot_id: str | None = None) -> str:
        """Operator control key: of one robot, or (``None``) of the whole fleet."""
        if robot_id is None:
            return f"{self.root}/control"
        return f"{self.root}/robot/{validate_id(robot_id)}/control"

    @property
    def all_states(self) -> str:
        return f"{self.root}/robot/*/state"

    @property
    def all_robot_controls(self) -> str:
        """Every robot's own control key (the fleet's is :meth:`control`)."""
        return f"{self.root}/robot/*/control"

    @property
    def obstacles(self) -> str:
        return f"{self.root}/obstacles"

    def alive(self, robot_id: str) -> str:
        return f"{self.root}/alive/{validate_id(robot_id)}"

    @property
    def all_alive(self) -> str:
        return f"{self.root}/alive/*"

    @property
    def service_alive(self) -> str:
        return f"{self.root}/alive/{SERVICE_TOKEN}"

    def robot_of(self, key: str) -> str | None:
        """Robot id in a ``.../robot/<id>/...``, ``.../alive/<id>`` or
        ``.../cell/<cx>/<cy>/<id>`` key, else None."""
        parts = key.split("/")
        if len(parts) == 6 and parts[:3] == ["parkfleet", self.fleet, "cell"]:
            return parts[5] if _ID_RE.fullmatch(parts[5]) else None
        if (
            len(parts) >= 4
            and parts[:2] == ["parkfleet", self.fleet]
            and parts[2] in ("robot", "alive")
            and _ID_RE.fullmatch(parts[3])
        ):
            return parts[3]
        return None


class Pose(BaseModel):
    """Planar posture in the world frame: x, y [m], theta [rad]."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    x: FiniteFloat
    y: FiniteFloat
    theta: FiniteFloat = 0.0

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.theta)


class RobotMode(StrEnum):
    """What a robot says it is doing (``lost`` is decided by the fleet, never sent)."""

    IDLE = "idle"
    DRIVING = "driving"
    AVOIDING = "avoiding"
    ARRIVED = "arrived"
    HOLDING = "holding"
    WAITING = "waiting"  # standing still on purpose: a planned start delay or a hold
    PAUSED = "paused"  # stopped by an operator's pause, task kept
    ESTOP = "estop"  # emergency stop latched until an operator's release, task kept


class ErrorLevel(StrEnum):
    """Severity of a robot fault (VDA 5050's levels, plus ``error`` in between)."""

    WARNING = "warning"  # the robot works on, degraded
    ERROR = "error"  # the robot cannot drive until the cause goes away by itself
    FATAL = "fatal"  # the robot cannot drive until an operator acts (e.g. e-stop release)


class RobotError(BaseModel):
    """One active fault of a robot: a stable ``code`` (e.g. ``pose_stale``), its level, a
    human message and ``since`` [s since epoch, robot's wall clock] when it began."""

    model_config = ConfigDict(frozen=True, extra="ignore")

    code: Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]{0,39}$")]
    level: ErrorLevel
    message: Annotated[str, Field(max_length=200)]
    since: FiniteFloat


#: Most faults a state carries (a robot has a handful of possible causes).
MAX_ROBOT_ERRORS = 16


class _Message(BaseModel):
    # Additive changes stay compatible: a receiver ignores top-level fields it does not
    # know (a robot on an older release keeps obeying a newer service); an incompatible
    # change bumps ``v``, which older receivers drop and count.
    model_config = ConfigDict(frozen=True, extra="ignore")

    v: Literal[1] = 1  # SCHEMA_VERSION


NonNegative = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


class Ahead(BaseModel):
    """A robot's prediction of itself (``RobotState.ahead``; docs/safety.md): where it
    will be when the command of this state (``u``, ``omega``) acts.

    ``x``, ``y`` [m], ``theta`` [rad]: the predicted posture (world frame), ``lead_s`` [s]
    after the state was sent (the robot's nominal command latency); ``spread_m`` [m]: a
    radius around the predicted axle centre holding the true one at that instant, and
    ``heading_rad`` [rad] the heading's; ``speed_m_s`` [m/s]: how fast the point the safety
    filter watches (``SafetyConfig.projection_m`` ahead of the axle) may move under its
    commands in flight and this one, actuation error included (a later command's bound
    rises by at most the fleet's ``SafetyConfig.max_accel_m_s2`` per second).
    """

    model_config = ConfigDict(frozen=True, extra="ignore")

    x: FiniteFloat
    y: FiniteFloat
    theta: FiniteFloat
    lead_s: NonNegative
    spread_m: NonNegative
    heading_rad: NonNegative
    speed_m_s: NonNegative

    def as_tuple(self) -> tuple[float, float, float, float, float, float, float]:
        return (
            self.x, self.y, self.theta, self.lead_s, self.spread_m, self.heading_rad,
            self.speed_m_s,
        )  # fmt: skip


class RobotState(_Message):
    """State a robot publishes at its control rate on ``robot/<id>/state``."""

    kind: Literal["state"] = "state"
    robot_id: RobotId
    seq: Annotated[int, Field(ge=0)]
    stamp: FiniteFloat  # sender's wall clock [s since epoch]
    pose: Pose
    u: FiniteFloat = 0.0  # commanded forward speed [m/s]
    omega: FiniteFloat = 0.0  # commanded turn rate [rad/s]
    mode: RobotMode = RobotMode.IDLE
    task_id: str | None = None  # task the robot is executing or has just finished
    revision: Annotated[int, Field(ge=0)] = 0  # revision of that task's assignment
    law: Law | None = None
    goal: Pose | None = None
    radius: Annotated[float, Field(gt=0, allow_inf_nan=False)] = 0.2  # body radius [m]
    #: Why the robot stands still, e.g. ``pose stale`` with mode ``holding``; None if driving.
    detail: Annotated[str, Field(max_length=200)] | None = None
    #: Active faults, oldest first.
    errors: Annotated[list[RobotError], Field(max_length=MAX_ROBOT_ERRORS)] = Field(
        default_factory=list
    )
    #: Where the robot predicts itself when this state's command acts (None: no prediction,
    #: a robot of an older release; peers then see it around its measured pose).
    ahead: Ahead | None = None


#: First byte of a compact state: its layout version (module docstring).
COMPACT_STATE_V1 = 0x01
_JSON_START = frozenset(b"{ \t\r\n")
_Finite = Annotated[float, msgspec.Meta(ge=-1e300, le=1e300)]  # rejects NaN and inf
_NonNegative = Annotated[float, msgspec.Meta(ge=0.0, le=1e300)]


class ErrorFrame(msgspec.Struct, array_like=True, frozen=True):
    """:class:`RobotError` in a compact state: ``[code, level, message, since]``."""

    code: Annotated[str, msgspec.Meta(pattern=r"^[a-z][a-z0-9_]{0,39}$")]
    level: ErrorLevel
    message: Annotated[str, msgspec.Meta(max_length=200)]
    since: _Finite


class StateFrame(msgspec.Struct, array_like=True, frozen=True):
    """Layout ``0x01`` of a compact :class:`RobotState`: a MessagePack array of these
    fields in this order (pose flattened to x, y, theta; goal as ``[x, y, theta]``).
    Append new fields at the end with a default; never reorder (module docstring)."""

    robot_id: Annotated[str, msgspec.Meta(pattern=_ID_RE.pattern)]
    seq: Annotated[int, msgspec.Meta(ge=0)]
    stamp: _Finite
    x: _Finite
    y: _Finite
    theta: _Finite
    u: _Finite = 0.0
    omega: _Finite = 0.0
    mode: RobotMode = RobotMode.IDLE
    task_id: str | None = None
    revision: Annotated[int, msgspec.Meta(ge=0)] = 0
    law: Law | None = None
    goal: tuple[_Finite, _Finite, _Finite] | None = None
    radius: Annotated[float, msgspec.Meta(gt=0, le=1e300)] = 0.2
    detail: Annotated[str, msgspec.Meta(max_length=200)] | None = None
    errors: Annotated[list[ErrorFrame], msgspec.Meta(max_length=MAX_ROBOT_ERRORS)] = []
    #: :class:`Ahead` as ``[x, y, theta, lead_s, spread_m, heading_rad, speed_m_s]``.
    ahead: (
        tuple[_Finite, _Finite, _Finite, _NonNegative, _NonNegative, _NonNegative, _NonNegative]
        | None
    ) = None


_frame_encoder = msgspec.msgpack.Encoder()
_frame_decoder = msgspec.msgpack.Decoder(StateFrame)
_STATE_FIELDS = frozenset(RobotState.model_fields)
_POSE_FIELDS = frozenset(Pose.model_fields)
_ERROR_FIELDS = frozenset(RobotError.model_fields)
_AHEAD_FIELDS = frozenset(Ahead.model_fields)
_set = object.__setattr__


def _trusted(cls: type[M], fields: dict[str, object], names: frozenset[str]) -> M:
    """A pydantic model from values msgspec already validated, without validating again
    (the hot path: a few hundred ns instead of pydantic's microseconds)."""
    model = cls.__new__(cls)
    _set(model, "__dict__", fields)
    _set(model, "__pydantic_fields_set__", set(names))
    _set(model, "__pydantic_extra__", None)
    _set(model, "__pydantic_private__", None)
    return model


def _pose(x: float, y: float, theta: float) -> Pose:
    return _trusted(Pose, {"x": x, "y": y, "theta": theta}, _POSE_FIELDS)


def encode_age(age_s: float) -> bytes:
    """Attachment of a replayed state: its age [s] as ASCII decimal (``"1.250"``)."""
    return f"{max(age_s, 0.0):.3f}".encode("ascii")


def parse_age(attachment: bytes | None) -> float | None:
    """The age [s] of a replayed state's attachment (:func:`encode_age`); None when absent
    or malformed (the receiver then drops the reply)."""
    if attachment is None or len(attachment) > 32:
        return None
    try:
        age = float(attachment.decode("ascii"))
    except (UnicodeDecodeError, ValueError):
        return None
    return age if math.isfinite(age) and age >= 0.0 else None


def encode_state(state: RobotState) -> bytes:
    """The compact encoding of ``state``: version byte ``0x01`` + MessagePack array."""
    p, g = state.pose, state.goal
    frame = StateFrame(
        state.robot_id, state.seq, state.stamp, p.x, p.y, p.theta, state.u, state.omega,
        state.mode, state.task_id, state.revision, state.law,
        None if g is None else (g.x, g.y, g.theta), state.radius, state.detail,
        [ErrorFrame(e.code, e.level, e.message, e.since) for e in state.errors],
        None if state.ahead is None else state.ahead.as_tuple(),
    )  # fmt: skip
    return b"\x01" + bytes(_frame_encoder.encode(frame))


def _from_frame(f: StateFrame) -> RobotState:
    g = f.goal
    errors = [
        _trusted(
            RobotError,
            {"code": e.code, "level": e.level, "message": e.message, "since": e.since},
            _ERROR_FIELDS,
        )
        for e in f.errors
    ]
    fields: dict[str, object] = {
        "v": SCHEMA_VERSION, "kind": "state", "robot_id": f.robot_id, "seq": f.seq,
        "stamp": f.stamp, "pose": _pose(f.x, f.y, f.theta), "u": f.u, "omega": f.omega,
        "mode": f.mode, "task_id": f.task_id, "revision": f.revision, "law": f.law,
        "goal": None if g is None else _pose(*g), "radius": f.radius, "detail": f.detail,
        "errors": errors, "ahead": None if f.ahead is None else _ahead(*f.ahead),
    }  # fmt: skip
    return _trusted(RobotState, fields, _STATE_FIELDS)


def _ahead(
    x: float, y: float, theta: float, lead_s: float, spread_m: float, heading_rad: float,
    speed_m_s: float,
) -> Ahead:  # fmt: skip
    fields: dict[str, object] = {
        "x": x, "y": y, "theta": theta, "lead_s": lead_s, "spread_m": spread_m,
        "heading_rad": heading_rad, "speed_m_s": speed_m_s,
    }  # fmt: skip
    return _trusted(Ahead, fields, _AHEAD_FIELDS)


def parse_state(payload: Payload) -> RobotState | Rejected:
    """A state in either encoding (compact: msgspec, no pydantic; JSON: pydantic), or why
    it is not one (``oversized``, ``version``, ``invalid``)."""
    raw = _raw(payload)
    if isinstance(raw, Rejected):
        return raw
    if not raw:
        return Rejected("invalid", "RobotState: empty payload")
    first = raw[0]
    if first == COMPACT_STATE_V1:
        try:
            return _from_frame(_frame_decoder.decode(memoryview(raw)[1:]))
        except msgspec.DecodeError as exc:  # ValidationError is a DecodeError
            return Rejected("invalid", f"RobotState (compact): {exc}")
    if first < 0x20 and first not in _JSON_START:
        return Rejected("version", f"RobotState: compact layout {first} unknown")
    try:
        return RobotState.model_validate_json(raw)
    except ValidationError as exc:
        return Rejected("invalid", f"RobotState: {exc.error_count()} error(s)")


def as_json(payload: Payload) -> str | Rejected:
    """Any message's JSON for people and tools: a compact state is decoded and written as
    the JSON it stands for; any other payload is returned as its text."""
    raw = _raw(payload)
    if isinstance(raw, Rejected):
        return raw
    if raw[:1] == b"\x01":
        state = parse_state(raw)
        return state if isinstance(state, Rejected) else state.model_dump_json()
    try:
        return raw.decode()
    except UnicodeDecodeError:
        return Rejected("invalid", "neither JSON nor a compact state")


class RobotDescription(_Message):
    """Robot -> fleet on ``robot/<id>/description``: what the robot is (module docstring).

    Fields flat (not a nested ``RobotProfile``) so a newer robot's extra fields are ignored
    by an older fleet. ``max_wheel_speed`` [rad/s] ``None`` = no limit (the paper's robot).
    """

    kind: Literal["description"] = "description"
    robot_id: RobotId
    radius: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)]  # body radius [m]
    wheel_radius: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)]  # [m]
    half_axle: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)]  # [m]
    max_wheel_speed: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    #: Whether the base may drive backwards (laws (17)/(20) reverse near the goal).
    may_reverse: bool = True
    #: Free text for people, e.g. ``TurtleBot 4 (Create 3)``.
    model: Annotated[str, Field(max_length=64)] | None = None

    @classmethod
    def of(
        cls,
        robot_id: str,
        profile: RobotProfile,
        *,
        may_reverse: bool = True,
        model: str | None = None,
    ) -> RobotDescription:
        """The description of a robot with ``profile``."""
        limit = profile.max_wheel_speed
        return cls(
            robot_id=robot_id,
            radius=profile.radius,
            wheel_radius=profile.wheel_radius,
            half_axle=profile.half_axle,
            max_wheel_speed=None if limit == math.inf else limit,
            may_reverse=may_reverse,
            model=model,
        )

    @property
    def profile(self) -> RobotProfile:
        """The robot's physical profile (Eq. 2, Table 10)."""
        return RobotProfile(
            wheel_radius=self.wheel_radius,
            half_axle=self.half_axle,
            max_wheel_speed=math.inf if self.max_wheel_speed is None else self.max_wheel_speed,
            radius=self.radius,
        )


#: Most via-points of one assignment's route.
MAX_ROUTE_POINTS = 64
#: [m] default pass-through radius of a route's via-points.
DEFAULT_PASS_M = 0.5


#: A via-point of a route: (x, y) [m], world frame.
ViaPoint = tuple[FiniteFloat, FiniteFloat]


class ParkAssignment(_Message):
    """Fleet -> robot: park at ``goal`` with ``law``; re-sent until acknowledged.

    ``revision``: the fleet re-planned this task; a higher revision of the current
    ``task_id`` replaces its law/gains, a repeat of the same or a lower revision is ignored
    (see the module docstring).

    ``route``: via-points (x, y) [m] the robot passes, in order, before the goal: it aims at
    each (facing it, turning the shorter way) and passes it when its centre comes within
    ``pass_m`` [m] (:func:`fleet.core.step.aim`); ``pass_m`` is at least the position
    tolerance. A revision's route replaces the route, taken from its first via-point again
    (the fleet plans it from where the robot is). Compatibility rule (``v`` stays 1): both
    fields are additive; without them the robot drives straight to its goal, as before. A
    robot of an older release ignores them and drives straight to its goal: its safety
    filter still keeps it off the walls, but it stops at a wall the route goes around, and
    the planner's prediction (which follows the route) is wrong for it. Upgrade the robots
    before giving a site walls that robots must drive around.

    ``avoidance.smoothing_m``: the width of Eq. (27)'s smoothed bands
    (:class:`fleet.core.params.Avoidance`). Compatibility rule (``v`` stays 1): absent means
    0, the paper's term, which is what a service of an older release plans with; a service
    sends it unless it is 0. A robot of an older release rejects an assignment carrying it
    (its ``avoidance`` forbids unknown fields: dropped and counted as ``invalid``): upgrade
    the robots before the service, or run the service with ``avoidance.smoothing_m = 0``
    until they are.
    """

    kind: Literal["park"] = "park"
    robot_id: RobotId
    task_id: Annotated[str, Field(min_length=1, max_length=64)]
    revision: Annotated[int, Field(ge=0)] = 0
    goal: Pose
    law: Law
    gains: Gains
    tolerance: Tolerance = Tolerance()
    max_wheel_speed: Annotated[float, Field(gt=0)] | None = None  # [rad/s]; None = robot's own
    avoidance: Avoidance = Avoidance()
    #: Stand still this long [s, robot time] after applying this revision, then drive.
    start_delay_s: Annotated[float, Field(ge=0.0, le=3600.0, allow_inf_nan=False)] = 0.0
    #: Stand still until a higher revision arrives (no safe option was found yet).
    hold: bool = False
    #: Leadership term of the sending service (0: no election); see the module docstring.
    term: Annotated[int, Field(ge=0)] = 0
    route: Annotated[list[ViaPoint], Field(max_length=MAX_ROUTE_POINTS)] = Field(
        default_factory=list
    )
    pass_m: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] = DEFAULT_PASS_M

    @field_validator("avoidance", mode="before")
    @classmethod
    def _absent_smoothing_is_the_papers_term(cls, value: Any) -> Any:
        if isinstance(value, dict) and "smoothing_m" not in value:
            return {**value, "smoothing_m": 0.0}
        return value

    @field_serializer("avoidance")
    def _papers_term_without_the_field(self, avoidance: Avoidance) -> dict[str, float]:
        """``smoothing_m`` = 0 is left out: a robot of an older release accepts it."""
        return avoidance.model_dump(
            exclude={"smoothing_m"} if avoidance.smoothing_m == 0.0 else None
        )

    @model_validator(mode="after")
    def _passes_beyond_tolerance(self) -> ParkAssignment:
        if self.route and self.pass_m < self.tolerance.position:
            raise ValueError(
                f"pass_m ({self.pass_m} m) must be at least the position tolerance "
                f"({self.tolerance.position} m): a robot would stop at a via-point"
            )
        return self


class CancelAssignment(_Message):
    """Fleet -> robot: stop working on ``task_id`` and hold still."""

    kind: Literal["cancel"] = "cancel"
    robot_id: RobotId
    task_id: Annotated[str, Field(min_length=1, max_length=64)]
    #: Leadership term of the sending service (0: no election); see the module docstring.
    term: Annotated[int, Field(ge=0)] = 0


Assignment = Annotated[ParkAssignment | CancelAssignment, Field(discriminator="kind")]


class ControlAction(StrEnum):
    """Operator commands (see the module docstring)."""

    PAUSE = "pause"
    RESUME = "resume"
    ESTOP = "estop"
    RELEASE = "release"


class ControlCommand(_Message):
    """Operator -> robots on ``control`` (fleet) or ``robot/<id>/control``; every agent obeys
    it directly. ``seq`` is increasing per ``issuer`` (see the module docstring)."""

    kind: Literal["control"] = "control"
    command: ControlAction
    robot_id: RobotId | None = None  # None: every robot of the fleet
    issuer: Annotated[str, Field(pattern=_ID_RE.pattern)]
    seq: Annotated[int, Field(ge=0)]
    stamp: FiniteFloat  # issuer's wall clock [s since epoch]
    reason: Annotated[str, Field(max_length=200)] | None = None
    #: Leadership term of a fleet service that sent it; 0 (operator tools): always obeyed.
    term: Annotated[int, Field(ge=0)] = 0


@dataclass(frozen=True)
class Hold:
    """The two operator latches of a robot (or the fleet): pause and e-stop, independent;
    :meth:`apply` is the one rule of how commands change them (module docstring)."""

    paused: bool = False
    estop: bool = False

    def apply(self, action: ControlAction) -> Hold:
        if action is ControlAction.PAUSE:
            return Hold(True, self.estop)
        if action is ControlAction.RESUME:
            return Hold(False, self.estop)
        if action is ControlAction.ESTOP:
            return Hold(self.paused, True)
        return Hold(self.paused, False)  # RELEASE

    @property
    def restrictive(self) -> ControlAction | None:
        """The command a robot must obey under this hold, if any."""
        if self.estop:
            return ControlAction.ESTOP
        if self.paused:
            return ControlAction.PAUSE
        return None


#: Issuers whose last sequence number a receiver remembers (oldest forgotten first).
MAX_ISSUERS = 64


class IssuerOrder:
    """The one ordering rule of operator commands: a command counts only if its ``seq`` is
    above the last one taken from its issuer (repeats and reordered copies are ignored); the
    last ``max_issuers`` issuers are remembered. Not thread-safe."""

    def __init__(self, max_issuers: int = MAX_ISSUERS) -> None:
        self.max_issuers = max_issuers
        self._last_seq: OrderedDict[str, int] = OrderedDict()

    def __len__(self) -> int:
        return len(self._last_seq)

    def accept(self, command: ControlCommand) -> bool:
        """Whether ``command`` is newer than its issuer's last one (then it is the last)."""
        last = self._last_seq.get(command.issuer)
        if last is not None and command.seq <= last:
            return False
        self._last_seq[command.issuer] = command.seq
        self._last_seq.move_to_end(command.issuer)
        while len(self._last_seq) > self.max_issuers:
            self._last_seq.popitem(last=False)
        return True


class TermFence:
    """The one fencing rule of a receiver (module docstring): a fleet message counts only if
    its ``term`` is not below the highest seen; operator commands (``ControlCommand`` with
    term 0) always count. ``dropped`` counts the fenced-off messages. Not thread-safe."""

    def __init__(self) -> None:
        self.highest = 0
        self.dropped = 0

    def accept(self, message: ParkAssignment | CancelAssignment | ControlCommand) -> bool:
        """Whether to obey ``message`` (then its term is the highest if it is higher)."""
        if isinstance(message, ControlCommand) and message.term == 0:
            return True
        if message.term < self.highest:
            self.dropped += 1
            return False
        self.highest = message.term
        return True


def obeys(action: ControlAction, mode: RobotMode) -> bool:
    """Whether a robot reporting ``mode`` shows it has applied ``action`` (a resume leaves an
    e-stopped robot e-stopped, and a pause an e-stopped one too)."""
    if action is ControlAction.ESTOP:
        return mode is RobotMode.ESTOP
    if action is ControlAction.RELEASE:
        return mode is not RobotMode.ESTOP
    if action is ControlAction.PAUSE:
        return mode in (RobotMode.PAUSED, RobotMode.ESTOP)
    return mode is not RobotMode.PAUSED  # RESUME


#: Body radius [m] of an obstacle sent without one (a post; see :class:`Obstacle`).
DEFAULT_OBSTACLE_BODY_M = 0.1


class Obstacle(BaseModel):
    """A static obstacle: a post at (x, y) [m], or with ``end`` a wall segment from (x, y)
    to ``end`` [m]; influence radius ``radius`` [m] of Eq. (27) (Section 6) around it and
    ``body`` radius [m] (a wall's half thickness), the solid part no robot's body may come
    within ``contact_margin_m`` of (the safety filter, :mod:`fleet.core.step`).

    Compatibility rules (``v`` stays 1):

    * ``body`` is additive. A payload without it gets :data:`DEFAULT_OBSTACLE_BODY_M` (a
      post), capped at the influence radius; an older robot ignores it and sees the paper's
      point obstacle.
    * ``end`` is additive. A payload without it is a post, as before. A robot of a release
      before walls forbids the unknown field, so it **drops the whole set** (counted as
      malformed) and keeps the obstacles it had: upgrade the robots before adding walls.
    * ``extra="forbid"`` is kept for the API's input, so the obstacle *set* on the wire
      ignores unknown fields of the set only.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    x: FiniteFloat
    y: FiniteFloat
    radius: Annotated[float, Field(gt=0, allow_inf_nan=False)] = 1.0
    body: Annotated[float, Field(ge=0, allow_inf_nan=False)] | None = None
    end: tuple[FiniteFloat, FiniteFloat] | None = None

    @model_validator(mode="after")
    def _body_within_influence(self) -> Obstacle:
        if self.body is not None and self.body > self.radius:
            raise ValueError(
                f"body ({self.body} m) must not exceed the influence radius ({self.radius} m)"
            )
        return self

    @property
    def body_radius(self) -> float:
        """The body radius [m]: ``body``, or the default for a payload without one."""
        return min(DEFAULT_OBSTACLE_BODY_M, self.radius) if self.body is None else self.body

    @property
    def far_end(self) -> tuple[float, float]:
        """The segment's far end [m]: ``end``, or the centre for a post."""
        return (self.x, self.y) if self.end is None else (float(self.end[0]), float(self.end[1]))

    def distance(self, x: float, y: float) -> float:
        """Distance [m] from (x, y) to the post's centre or the wall's segment."""
        return segment_distance(x, y, (self.x, self.y), self.far_end)


class ObstacleSet(_Message):
    """All static obstacles of the yard, published whole (latest wins)."""

    kind: Literal["obstacles"] = "obstacles"
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=1000)


M = TypeVar("M", bound=BaseModel)
_assignment_adapter: TypeAdapter[ParkAssignment | CancelAssignment] = TypeAdapter(Assignment)


def encode(message: BaseModel) -> bytes:
    """Serialise a message to compact JSON bytes."""
    return message.model_dump_json().encode()


@dataclass(frozen=True)
class Rejected:
    """Why a payload is not a valid message: ``reason`` (a short counter key) and detail."""

    reason: str
    detail: str


Payload = bytes | bytearray | memoryview | str


def _raw(payload: Payload) -> bytes | Rejected:
    raw = payload.encode() if isinstance(payload, str) else bytes(payload)
    if len(raw) > MAX_PAYLOAD_BYTES:
        return Rejected("oversized", f"{len(raw)} bytes")
    return raw


def parse(model: type[M], payload: Payload) -> M | Rejected:
    """Validate ``payload`` (JSON) as ``model``, or say why it is not one."""
    if model is RobotState:  # the hot message: either encoding (module docstring)
        return parse_state(payload)  # type: ignore[return-value]
    raw = _raw(payload)
    if isinstance(raw, Rejected):
        return raw
    try:
        return model.model_validate_json(raw)
    except ValidationError as exc:
        return Rejected("invalid", f"{model.__name__}: {exc.error_count()} error(s)")


def parse_assignment(payload: Payload) -> ParkAssignment | CancelAssignment | Rejected:
    """Validate a park or cancel assignment, or say why it is not one."""
    raw = _raw(payload)
    if isinstance(raw, Rejected):
        return raw
    try:
        return _assignment_adapter.validate_json(raw)
    except ValidationError as exc:
        return Rejected("invalid", f"assignment: {exc.error_count()} error(s)")
