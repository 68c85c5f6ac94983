"""Operator control of one robot: pause / resume and the e-stop latch (pure, no I/O).

:class:`OperatorLatch` applies :class:`fleet.core.wire.ControlCommand` messages (rules in the
``fleet.core.wire`` module docstring, after VDA 5050's ``startPause``/``stopPause`` and its
emergency stop) and tells the control loop whether to override the task:

* ``estop`` latches until ``release`` -> mode ``estop``; wins over everything;
* ``pause`` holds until ``resume`` -> mode ``paused``;
* commands of one issuer apply in ``seq`` order: a repeat, or an older command arriving
  after a newer one, is ignored. The last ``MAX_ISSUERS`` issuers are remembered.

Not thread-safe: the agent applies commands on its control thread (``RobotAgent.tick``).
"""

from __future__ import annotations

from fleet.core.wire import ControlAction, ControlCommand, Hold, IssuerOrder, RobotMode

_MODE_OF: dict[ControlAction | None, RobotMode] = {
    ControlAction.ESTOP: RobotMode.ESTOP,
    ControlAction.PAUSE: RobotMode.PAUSED,
}


class OperatorLatch:
    """The operator's hold on one robot: paused, e-stopped, and why."""

    def __init__(self, robot_id: str) -> None:
        self.robot_id = robot_id
        self.hold = Hold()
        self._why: dict[ControlAction, str] = {}  # pause / estop -> "by <issuer>: <reason>"
        self._order = IssuerOrder()
        self.applied = 0
        self.ignored = 0  # repeats, reordered copies, commands for other robots

    def apply(self, command: ControlCommand) -> bool:
        """Apply ``command`` if it is for this robot and newer than the issuer's last one."""
        if command.robot_id not in (None, self.robot_id):
            self.ignored += 1
            return False
        if not self._order.accept(command):
            self.ignored += 1
            return False
        action = command.command
        if action in (ControlAction.PAUSE, ControlAction.ESTOP):
            why = f"by {command.issuer}" + (f": {command.reason}" if command.reason else "")
            self._why[action] = why
        self.hold = self.hold.apply(action)
        self.applied += 1
        return True

    @property
    def paused(self) -> bool:
        return self.hold.paused

    @property
    def estop(self) -> bool:
        return self.hold.estop

    @property
    def mode(self) -> RobotMode | None:
        """The mode that overrides the task (``estop`` or ``paused``), or None."""
        return _MODE_OF.get(self.hold.restrictive)

    @property
    def detail(self) -> str | None:
        """Why the operator holds the robot, e.g. ``emergency stop by cli-host: drill``."""
        if self.estop:
            return f"emergency stop {self._why[ControlAction.ESTOP]}"
        if self.paused:
            return f"paused {self._why[ControlAction.PAUSE]}"
        return None
