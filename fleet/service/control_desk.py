"""The fleet service's side of operator control: what was asked, and holding to it (pure).

:class:`ControlDesk` issues ``ControlCommand``s for the service (issuer ``fleet-service``,
``seq`` increasing from the wall clock in microseconds, so a restarted service still sends
newer numbers) and remembers the state it asked for: fleet-wide (``paused``, ``estop``) and
per robot (a fleet-wide command clears the per-robot ones, as it applies to every robot).

Commands other tools issued (``parkfleet estop`` from another process, seen on the control
keys) are :meth:`ControlDesk.adopt`-ed by the same rule, in each issuer's ``seq`` order
(:class:`fleet.core.wire.IssuerOrder`): the desk mirrors what is latched whoever latched it,
so the service re-sends a CLI's e-stop to a robot that joins later, and never re-sends an
e-stop that the CLI released.

It re-asserts only the *restrictive* states: when a robot that should be e-stopped (or
paused) reports a mode that does not obey (it restarted, joined later, or lost the message),
:meth:`ControlDesk.check` returns the command again for that robot, at most every
``RESEND_S``. It never re-sends a release or a resume on its own: an e-stop that another
tool (``parkfleet estop``) latched stays latched until someone releases it.

Pure and not thread-safe: the service calls it under its lock with the time as arguments
(``now`` [s, monotonic], ``wall`` [s since epoch]) and publishes the commands it returns
through its outbox, after releasing the lock. :meth:`ControlDesk.check` is on the service's
hot path (every robot state): one attribute read when no robot is held.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from pydantic import BaseModel, ConfigDict

from fleet.core.wire import ControlAction, ControlCommand, Hold, IssuerOrder, RobotState, obeys

ISSUER = "fleet-service"
#: Seconds between re-sends of a restrictive command to a robot that does not obey it.
RESEND_S = 0.5
_NEVER = float("-inf")


@dataclass(frozen=True)
class ControlState:
    """What the operator asked: the fleet-wide hold, and robots with a command of their own
    since the last fleet-wide one (with the reasons given)."""

    fleet: Hold
    robots: dict[str, Hold]
    fleet_reason: str | None = None
    robot_reasons: dict[str, str | None] = field(default_factory=dict)


class _HoldDoc(BaseModel):
    paused: bool = False
    estop: bool = False


class OperatorRecord(BaseModel):
    """What operators asked that outlives the service process, stored as one JSON document
    (``KEY``): the desk's holds and reasons, and the robots out of service."""

    KEY: ClassVar[str] = "operator"
    model_config = ConfigDict(extra="ignore")

    v: int = 1
    fleet: _HoldDoc = _HoldDoc()
    robots: dict[str, _HoldDoc] = {}
    fleet_reason: str | None = None
    robot_reasons: dict[str, str | None] = {}
    out_of_service: list[str] = []

    @classmethod
    def of(cls, state: ControlState, out_of_service: list[str]) -> OperatorRecord:
        def doc(hold: Hold) -> _HoldDoc:
            return _HoldDoc(paused=hold.paused, estop=hold.estop)

        return cls(
            fleet=doc(state.fleet),
            robots={rid: doc(h) for rid, h in state.robots.items()},
            fleet_reason=state.fleet_reason,
            robot_reasons=dict(state.robot_reasons),
            out_of_service=sorted(out_of_service),
        )

    def control_state(self) -> ControlState:
        return ControlState(
            Hold(self.fleet.paused, self.fleet.estop),
            {rid: Hold(h.paused, h.estop) for rid, h in self.robots.items()},
            self.fleet_reason,
            dict(self.robot_reasons),
        )


class ControlDesk:
    """Issues operator commands for the service and holds the robots to them."""

    def __init__(self) -> None:
        self._fleet = Hold()
        self._robots: dict[str, Hold] = {}
        self._holding = False  # some hold is restrictive (else check() returns at once)
        self._reasons: dict[str | None, str | None] = {}  # robot (None: fleet) -> reason
        self._resent_at: dict[str, float] = {}  # robot -> last re-send [s, monotonic]
        self._last_seq = 0
        self._order = IssuerOrder()  # of the commands adopted from other issuers

    def _message(
        self, action: ControlAction, robot_id: str | None, reason: str | None, wall: float
    ) -> ControlCommand:
        self._last_seq = max(self._last_seq + 1, int(wall * 1e6))
        return ControlCommand(
            command=action,
            robot_id=robot_id,
            issuer=ISSUER,
            seq=self._last_seq,
            stamp=wall,
            reason=reason,
        )

    def command(
        self, action: ControlAction, robot_id: str | None, reason: str | None, wall: float
    ) -> ControlCommand:
        """Record ``action`` for one robot or (``None``) the whole fleet; returns the
        command to publish."""
        self._record(action, robot_id, reason)
        return self._message(action, robot_id, reason, wall)

    def _record(self, action: ControlAction, robot_id: str | None, reason: str | None) -> None:
        if robot_id is None:
            self._fleet = self._fleet.apply(action)
            self._robots.clear()
            self._reasons = {None: reason}
        else:
            self._robots[robot_id] = self.hold(robot_id).apply(action)
            self._reasons[robot_id] = reason
        self._note_holding()

    def _note_holding(self) -> None:
        self._holding = self._fleet.restrictive is not None or any(
            h.restrictive is not None for h in self._robots.values()
        )

    def adopt(self, command: ControlCommand) -> bool:
        """Take up a command another tool issued (its own issuer, seen on the bus); False if
        it is the service's own, a repeat or older than one already taken from its issuer."""
        if command.issuer == ISSUER or not self._order.accept(command):
            return False
        given = command.reason
        why = command.issuer if given is None else f"{given} ({command.issuer})"
        self._record(command.command, command.robot_id, why)
        return True

    def hold(self, robot_id: str) -> Hold:
        """What the operator asked of ``robot_id`` (its own command, else the fleet's)."""
        return self._robots.get(robot_id, self._fleet)

    def reason(self, robot_id: str) -> str | None:
        """The reason given with the command that holds ``robot_id``."""
        return self._reasons.get(robot_id, self._reasons.get(None))

    @property
    def fleet(self) -> Hold:
        return self._fleet

    def state(self) -> ControlState:
        robot_reasons = {rid: why for rid, why in self._reasons.items() if rid is not None}
        return ControlState(self._fleet, dict(self._robots), self._reasons.get(None), robot_reasons)

    def restore(self, state: ControlState) -> None:
        """Take up the holds a previous run of the service asked for (no command sent:
        :meth:`check` re-sends them to robots that do not obey)."""
        self._fleet = state.fleet
        self._robots = dict(state.robots)
        self._reasons = {None: state.fleet_reason}
        self._reasons.update(state.robot_reasons)
        self._note_holding()

    def check(self, state: RobotState, now: float, wall: float) -> ControlCommand | None:
        """The restrictive command a robot reporting ``state`` does not obey, to send again
        (None: it obeys, nothing is asked, or it was re-sent less than ``RESEND_S`` ago)."""
        if not self._holding:
            return None
        rid = state.robot_id
        action = self._robots.get(rid, self._fleet).restrictive
        if action is None or obeys(action, state.mode):
            return None
        if now - self._resent_at.get(rid, _NEVER) < RESEND_S:
            return None
        self._resent_at[rid] = now
        return self._message(action, rid, self.reason(rid), wall)

    def forget(self, robot_id: str) -> None:
        """The robot was removed from the fleet: what is kept for it goes (bounded)."""
        if self._robots.pop(robot_id, None) is not None:
            self._note_holding()
        self._reasons.pop(robot_id, None)
        self._resent_at.pop(robot_id, None)
