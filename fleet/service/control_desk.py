"""The fleet service's side of operator control: what was asked, and holding to it.

:class:`ControlDesk` issues ``ControlCommand``s for the service (issuer ``fleet-service``,
``seq`` increasing from the wall clock in microseconds, so a restarted service still sends
newer numbers) and remembers the state it asked for: fleet-wide (``paused``, ``estop``) and
per robot (a fleet-wide command clears the per-robot ones, as it applies to every robot).

It re-asserts only the *restrictive* states: when a robot that should be e-stopped (or
paused) reports a mode that does not obey (it restarted, joined later, or lost the message),
the command is sent again to that robot, at most every ``RESEND_S``. It never re-sends a
release or a resume on its own: an e-stop that another tool (``parkfleet estop``) latched
stays latched until someone releases it.

Pure apart from the injected ``publish`` and clock; thread-safe (one lock, never held while
publishing).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from fleet.core.wire import ControlAction, ControlCommand, Hold, RobotMode, RobotState, obeys

ISSUER = "fleet-service"
#: Seconds between re-sends of a restrictive command to a robot that does not obey it.
RESEND_S = 0.5


class ControlDesk:
    """Issues operator commands for the service and holds the robots to them."""

    def __init__(
        self,
        publish: Callable[[ControlCommand], None],
        clock: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self._publish = publish
        self._clock = clock
        self._monotonic = monotonic
        self._lock = threading.Lock()
        self._fleet = Hold()
        self._robots: dict[str, Hold] = {}
        self._last_seq = 0
        self._reasons: dict[str | None, str | None] = {}
        self._resent: dict[str, float] = {}
        self.requested: dict[ControlAction, int] = dict.fromkeys(ControlAction, 0)
        self.resent = 0

    def command(
        self, action: ControlAction, robot_id: str | None = None, reason: str | None = None
    ) -> ControlCommand:
        """Record and publish ``action`` for one robot or (``None``) the whole fleet."""
        with self._lock:
            now = self._clock()
            self._last_seq = max(self._last_seq + 1, int(now * 1e6))
            message = ControlCommand(
                command=action,
                robot_id=robot_id,
                issuer=ISSUER,
                seq=self._last_seq,
                stamp=now,
                reason=reason,
            )
            if robot_id is None:
                self._fleet = self._fleet.apply(action)
                self._robots.clear()
                self._reasons = {None: reason}
            else:
                self._robots[robot_id] = self.hold(robot_id).apply(action)
                self._reasons[robot_id] = reason
            self.requested[action] += 1
        self._publish(message)
        return message

    def hold(self, robot_id: str) -> Hold:
        """What the operator asked of ``robot_id`` (its own command, else the fleet's)."""
        return self._robots.get(robot_id, self._fleet)

    @property
    def fleet(self) -> Hold:
        return self._fleet

    def robots(self) -> dict[str, Hold]:
        """Robots with a command of their own since the last fleet-wide one."""
        with self._lock:
            return dict(self._robots)

    def held(self, robot_id: str, mode: RobotMode | None = None) -> bool:
        """Whether the robot must stand still: asked to, or reporting paused / e-stopped."""
        if mode in (RobotMode.PAUSED, RobotMode.ESTOP):
            return True
        with self._lock:
            return self.hold(robot_id).restrictive is not None

    def check(self, state: RobotState) -> None:
        """Re-send the restrictive command a robot reporting ``state`` does not obey."""
        with self._lock:
            action = self.hold(state.robot_id).restrictive
            if action is None or obeys(action, state.mode):
                return
            now = self._monotonic()
            if now - self._resent.get(state.robot_id, float("-inf")) < RESEND_S:
                return
            self._resent[state.robot_id] = now
            self._last_seq = max(self._last_seq + 1, int(self._clock() * 1e6))
            message = ControlCommand(
                command=action,
                robot_id=state.robot_id,
                issuer=ISSUER,
                seq=self._last_seq,
                stamp=self._clock(),
                reason=self._reasons.get(state.robot_id, self._reasons.get(None)),
            )
            self.resent += 1
        self._publish(message)
