"""The fleet's roster: which robots exist, where they are and what they do.

Pure and not thread-safe (the service guards it with its lock); times come in as
arguments: ``now`` [s, monotonic] for every interval, ``wall`` [s since epoch] for display.

* A robot enters the roster with its first ``RobotState`` or liveliness news.
* Its liveliness token appearing marks it alive; the token disappearing marks it ``lost``.
  A lost robot keeps its last pose and stays an obstacle; a state that arrives after the
  token went away (reordered or late) updates the pose but not the status, and only a new
  token brings the robot back.
* Everything the service keeps per robot lives in its :class:`RobotRecord` (throttling of
  robot events, rate measurement, cancel re-sends), so removing a robot forgets all of it.
  A robot lost (or silent without any token) for longer than the retention time is
  :meth:`Roster.expired`; the service removes it (:meth:`Roster.remove`), as does an operator.
* Each robot's :class:`~fleet.core.wire.RobotDescription` (what it says it is: radius,
  wheels, limit, may it reverse) is kept in its record, one per robot (a newer one
  replaces it) and forgotten with the robot; a robot without one (an older release) is
  planned with the host's own profile and shown ``described: false``
  (:meth:`Roster.profile_of`).
* Parked robots (arrived, holding, paused, e-stopped or lost) are kept in a grid
  (:class:`GoalIndex`), so the goal check of a new task looks at the few robots near the
  goal, not at the whole fleet.
* An operator takes a robot out of service (:meth:`Roster.set_in_service`): it gets no
  task, and once lost it is no obstacle any more (it was taken away): it leaves the grid.

:meth:`Roster.update` is the hot path (every state of every robot, 50 Hz each): it stores
the state, keeps the cached status and reports whether status or task changed, building no
model; :meth:`Roster.view` builds the ``RobotView`` only when an event or a reader needs it.

:attr:`Roster.version` rises with every change a plan depends on -- a robot joining, lost,
removed, described, (de)commissioned, or changing status, task or detail -- and not with
poses: the service compares it (with the ledger's) to tell a stale plan.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from fleet.core.goals import GoalIndex, Occupied
from fleet.core.params import RobotProfile
from fleet.core.tasks import RobotStatus, RobotView
from fleet.core.wire import RobotDescription, RobotMode, RobotState

_STATUS_OF_MODE: dict[RobotMode, RobotStatus] = {m: RobotStatus(m.value) for m in RobotMode}
#: Statuses of a robot that stands where it is for good (it blocks goals near it).
PARKED = frozenset(
    {
        RobotStatus.ARRIVED,
        RobotStatus.HOLDING,
        RobotStatus.PAUSED,
        RobotStatus.ESTOP,
        RobotStatus.LOST,
    }
)
#: Statuses of a robot that an operator holds still (pause, e-stop), as it reports them.
OPERATOR_HELD = frozenset({RobotStatus.PAUSED, RobotStatus.ESTOP})
#: A parked robot that moved this far is moved in the grid [m].
_PARKED_MOVE_M = 0.05
_NEVER = -math.inf


@dataclass(frozen=True)
class ParkedRobot(Occupied):
    """A parked robot in the grid: where it stands, and which robot it is."""

    robot_id: str


@dataclass(slots=True)
class RobotRecord:
    """Everything the service knows and keeps about one robot."""

    robot_id: str
    state: RobotState | None = None
    token: bool | None = None  # None: no liveliness news yet; True: token present
    status: RobotStatus | None = None  # None until the pose is known
    seen: float = _NEVER  # its last state arrived at [s, monotonic]
    seen_wall: float = 0.0  # last state or liveliness news [s since epoch] (display)
    lost_since: float | None = None  # token gone at [s, monotonic]
    event_at: float = _NEVER  # last robot event announced [s, monotonic]
    rate_seq: int = -1  # anchor of the control-rate measurement: state seq ...
    rate_at: float = _NEVER  # ... and when it arrived [s, monotonic]
    cancel_at: float = _NEVER  # last cancel sent to it [s, monotonic]
    stray_at: float = _NEVER  # last check of a task it drives that is not its own
    parked_at: tuple[float, float] | None = None  # where it is in the parked grid [m]
    in_service: bool = True  # False: decommissioned by an operator (gets no task)
    description: RobotDescription | None = None  # what it says it is (None: never said)

    @property
    def task_id(self) -> str | None:
        return None if self.state is None else self.state.task_id

    @property
    def gone_for_good(self) -> bool:
        """Lost and decommissioned: taken out of the yard, no obstacle any more."""
        return self.token is False and not self.in_service


class Roster:
    """Latest state and liveliness of every robot seen (see the module docstring)."""

    def __init__(self, parked_cell: float = 1.0) -> None:
        self._robots: dict[str, RobotRecord] = {}
        self._parked = GoalIndex(parked_cell)
        self._unlinked: dict[str, None] = {}  # robots lost or without a token (retention)
        self._out_of_service_unseen: set[str] = set()  # decommissioned, not seen since start
        self._version = 0  # see the module docstring

    @property
    def version(self) -> int:
        """Rises with every change a plan depends on (not with poses)."""
        return self._version

    def __len__(self) -> int:
        return len(self._robots)

    def __contains__(self, robot_id: object) -> bool:
        return robot_id in self._robots

    def known(self, robot_id: str) -> bool:
        """Whether the robot has been seen at all (state or token)."""
        return robot_id in self._robots

    def record(self, robot_id: str) -> RobotRecord | None:
        return self._robots.get(robot_id)

    def records(self) -> Iterator[RobotRecord]:
        return iter(self._robots.values())

    def _entry(self, robot_id: str) -> RobotRecord:
        rec = self._robots.get(robot_id)
        if rec is None:
            rec = self._robots[robot_id] = RobotRecord(robot_id)
            self._unlinked[robot_id] = None
            if robot_id in self._out_of_service_unseen:
                self._out_of_service_unseen.discard(robot_id)
                rec.in_service = False
        return rec

    def update(self, state: RobotState, now: float, wall: float) -> tuple[RobotRecord, bool]:
        """Record a state; returns the robot's record and whether its status or task changed."""
        rec = self._robots.get(state.robot_id) or self._entry(state.robot_id)
        before = rec.state
        rec.state = state
        rec.seen = now
        rec.seen_wall = wall
        status = RobotStatus.LOST if rec.token is False else _STATUS_OF_MODE[state.mode]
        changed = (
            before is None
            or status is not rec.status
            or before.task_id != state.task_id
            or before.detail != state.detail
        )
        if status is not rec.status:
            rec.status = status
            self._place(rec)
        elif rec.parked_at is not None:
            px, py = rec.parked_at
            if abs(state.pose.x - px) + abs(state.pose.y - py) > _PARKED_MOVE_M:
                self._place(rec)
        self._version += changed
        return rec, changed

    def alive(self, robot_id: str, wall: float) -> RobotRecord:
        """The robot's liveliness token appeared."""
        rec = self._entry(robot_id)
        rec.token = True
        rec.lost_since = None
        self._version += 1
        rec.seen_wall = wall
        self._unlinked.pop(robot_id, None)
        self._restatus(rec)
        return rec

    def gone(self, robot_id: str, now: float) -> RobotRecord:
        """The robot's token disappeared: it is ``lost`` (kept at its last pose)."""
        rec = self._entry(robot_id)
        rec.token = False
        rec.lost_since = now
        self._version += 1
        self._unlinked[robot_id] = None
        self._restatus(rec)
        return rec

    def _restatus(self, rec: RobotRecord) -> None:
        if rec.state is None:
            return
        status = RobotStatus.LOST if rec.token is False else _STATUS_OF_MODE[rec.state.mode]
        if status is not rec.status:
            rec.status = status
            self._place(rec)

    def describe(self, description: RobotDescription) -> tuple[RobotRecord, bool]:
        """Keep the robot's description (it replaces an older one); returns the record and
        whether anything changed (a repeat of the same description changes nothing)."""
        rec = self._entry(description.robot_id)
        changed = rec.description != description
        rec.description = description
        self._version += changed
        return rec, changed

    def profile_of(self, robot_id: str, default: RobotProfile) -> RobotProfile:
        """The robot's own profile, or ``default`` (the host's) if it has not described
        itself."""
        rec = self._robots.get(robot_id)
        if rec is None or rec.description is None:
            return default
        return rec.description.profile

    def set_in_service(self, robot_id: str, in_service: bool) -> RobotRecord | None:
        """Decommission (False) or commission (True) a known robot; None if unknown."""
        rec = self._robots.get(robot_id)
        if rec is not None and rec.in_service is not in_service:
            rec.in_service = in_service
            self._place(rec)
            self._version += 1
        return rec

    def restore_out_of_service(self, robot_ids: list[str]) -> None:
        """Robots decommissioned before the service restarted: out of service once seen."""
        for rid in robot_ids:
            rec = self._robots.get(rid)
            if rec is None:
                self._out_of_service_unseen.add(rid)
            else:
                self.set_in_service(rid, False)

    def out_of_service(self) -> list[str]:
        """Every robot decommissioned (seen since the start or not), sorted."""
        seen = [rid for rid, rec in self._robots.items() if not rec.in_service]
        return sorted([*seen, *self._out_of_service_unseen])

    def _place(self, rec: RobotRecord) -> None:
        """Put the robot in (or take it out of) the parked grid according to its status."""
        if rec.status in PARKED and rec.state is not None and not rec.gone_for_good:
            p = rec.state.pose
            what = f"{rec.status.value} robot {rec.robot_id}"
            self._parked.add(rec.robot_id, ParkedRobot(p.x, p.y, what, rec.robot_id))
            rec.parked_at = (p.x, p.y)
        elif rec.parked_at is not None:
            self._parked.remove(rec.robot_id)
            rec.parked_at = None

    def parked_near(self, x: float, y: float, radius: float) -> list[ParkedRobot]:
        """Parked robots (arrived, holding, paused, e-stopped, lost but not decommissioned)
        within ``radius`` [m] of (x, y), nearest first."""
        return [p for p in self._parked.near(x, y, radius) if isinstance(p, ParkedRobot)]

    def is_lost(self, robot_id: str) -> bool:
        rec = self._robots.get(robot_id)
        return rec is not None and rec.token is False

    def state(self, robot_id: str) -> RobotState | None:
        rec = self._robots.get(robot_id)
        return None if rec is None else rec.state

    def expired(self, now: float, retention_s: float) -> list[str]:
        """Robots lost, or seen without any liveliness token, for ``retention_s`` [s] or more."""
        out = []
        for rid in self._unlinked:
            rec = self._robots[rid]
            since = rec.lost_since if rec.token is False else rec.seen
            if since is not None and now - since >= retention_s:
                out.append(rid)
        return out

    def remove(self, robot_id: str) -> RobotRecord | None:
        """Forget a robot and everything kept about it."""
        rec = self._robots.pop(robot_id, None)
        self._unlinked.pop(robot_id, None)
        self._version += rec is not None
        if rec is not None and rec.parked_at is not None:
            self._parked.remove(robot_id)
        return rec

    @staticmethod
    def view_of(rec: RobotRecord) -> RobotView | None:
        """The robot's view, or None if its pose is not known yet."""
        s = rec.state
        if s is None or rec.status is None:
            return None
        d = rec.description
        # The state is a validated message: build the view without validating again.
        return RobotView.model_construct(
            robot_id=s.robot_id,
            status=rec.status,
            pose=s.pose,
            u=s.u,
            omega=s.omega,
            task_id=s.task_id,
            law=s.law,
            goal=s.goal,
            radius=s.radius if d is None else d.radius,
            last_seen=rec.seen_wall,
            detail=s.detail,
            in_service=rec.in_service,
            errors=s.errors,
            described=d is not None,
            max_wheel_speed=None if d is None else d.max_wheel_speed,
            max_speed=None if d is None else _max_speed(d),
            may_reverse=True if d is None else d.may_reverse,
            model=None if d is None else d.model,
        )

    def view(self, robot_id: str) -> RobotView | None:
        rec = self._robots.get(robot_id)
        return None if rec is None else self.view_of(rec)

    def views(self) -> list[RobotView]:
        """Views of every robot with a known pose, sorted by id."""
        out = [self.view_of(self._robots[rid]) for rid in sorted(self._robots)]
        return [v for v in out if v is not None]

    def sizes(self) -> dict[str, int]:
        """How many entries each per-robot structure holds (bounded with the roster)."""
        return {"robots": len(self._robots), "parked_robots": len(self._parked)}


def _max_speed(d: RobotDescription) -> float | None:
    """Top forward speed [m/s] of a described robot (None: no wheel limit)."""
    return None if d.max_wheel_speed is None else d.max_wheel_speed * d.wheel_radius
