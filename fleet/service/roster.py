"""The fleet's roster: which robots exist, where they are and what they do.

Pure and not thread-safe (the service guards it with its lock); times come in as
arguments [s, service clock].

* A robot enters the roster with its first ``RobotState`` (its pose is unknown before).
* Its liveliness token appearing marks it alive; the token disappearing marks it ``lost``.
  A lost robot keeps its last pose and stays an obstacle; a state that arrives after the
  token went away (reordered or late) updates the pose but not the status, and only a new
  token brings the robot back.
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.core.tasks import RobotStatus, RobotView
from fleet.core.wire import RobotState


@dataclass
class _Entry:
    state: RobotState | None = None
    token: bool | None = None  # None: no liveliness news yet; True: token present
    last_seen: float = 0.0


class Roster:
    """Latest state and liveliness of every robot seen."""

    def __init__(self) -> None:
        self._robots: dict[str, _Entry] = {}

    def update(self, state: RobotState, now: float) -> tuple[RobotView, bool]:
        """Record a state; returns the new view and whether status or task changed."""
        entry = self._robots.setdefault(state.robot_id, _Entry())
        before = self.view(state.robot_id)
        entry.state = state
        entry.last_seen = now
        after = self.view(state.robot_id)
        assert after is not None
        changed = before is None or (before.status, before.task_id, before.detail) != (
            after.status,
            after.task_id,
            after.detail,
        )
        return after, changed

    def alive(self, robot_id: str, now: float) -> RobotView | None:
        """The robot's liveliness token appeared; returns its view if its pose is known."""
        entry = self._robots.setdefault(robot_id, _Entry())
        entry.token = True
        entry.last_seen = now
        return self.view(robot_id)

    def gone(self, robot_id: str, now: float) -> RobotView | None:
        """The robot's token disappeared: it is ``lost`` (kept at its last pose)."""
        entry = self._robots.setdefault(robot_id, _Entry())
        entry.token = False
        return self.view(robot_id)

    def is_lost(self, robot_id: str) -> bool:
        entry = self._robots.get(robot_id)
        return entry is not None and entry.token is False

    def state(self, robot_id: str) -> RobotState | None:
        entry = self._robots.get(robot_id)
        return None if entry is None else entry.state

    def known(self, robot_id: str) -> bool:
        """Whether the robot has been seen at all (state or token)."""
        return robot_id in self._robots

    def view(self, robot_id: str) -> RobotView | None:
        """The robot's view, or None if unknown or its pose is not known yet."""
        entry = self._robots.get(robot_id)
        if entry is None or entry.state is None:
            return None
        s = entry.state
        status = RobotStatus.LOST if entry.token is False else RobotStatus.from_mode(s.mode)
        return RobotView(
            robot_id=s.robot_id,
            status=status,
            pose=s.pose,
            u=s.u,
            omega=s.omega,
            task_id=s.task_id,
            law=s.law,
            goal=s.goal,
            radius=s.radius,
            last_seen=entry.last_seen,
            detail=s.detail,
            errors=s.errors,
        )

    def views(self) -> list[RobotView]:
        """Views of every robot with a known pose, sorted by id."""
        out = [self.view(rid) for rid in sorted(self._robots)]
        return [v for v in out if v is not None]
