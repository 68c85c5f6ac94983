"""Operator controls: pause, resume, e-stop and release robots; take them out of service.

A command is published first, in a batch of its own (never delayed by a store write); the
:class:`~fleet.service.control_desk.ControlDesk` remembers it, and a robot held still (as
asked, or as it reports) is an operator hold in the ledger. What operators asked is stored
(:class:`~fleet.service.control_desk.OperatorRecord`) and restored on start.
"""

from __future__ import annotations

import logging

from fleet.core.tasks import (
    RobotEvent,
    RobotNotFound,
    RobotView,
)
from fleet.core.wire import (
    ControlAction,
    ControlCommand,
)
from fleet.service.control_desk import ControlState, OperatorRecord
from fleet.service.effects import Effects, Publish, SaveState
from fleet.service.roster import OPERATOR_HELD, RobotRecord, Roster
from fleet.service.service_state import ServiceState

_log = logging.getLogger(__name__)


class OperatorControls(ServiceState):
    """The operator controls of one fleet service (docs/operating.md)."""

    def _stored_operator_record(self) -> OperatorRecord | None:
        """What operators asked before a restart (holds, robots out of service), if stored
        and readable (an unreadable one is logged and counted, and ignored)."""
        raw = self._store.load_state(OperatorRecord.KEY)
        if raw is None:
            return None
        try:
            return OperatorRecord.model_validate_json(raw)
        except ValueError:
            self._counters.add("operator_state_unreadable")
            _log.exception("stored operator state unreadable: starting without it")
            return None

    def _operator_saved(self) -> SaveState:
        """The operator record as it is now, to store (call with the lock held)."""
        record = OperatorRecord.of(self._desk.state(), self._roster.out_of_service())
        return SaveState(OperatorRecord.KEY, record.model_dump_json())

    def _hold_reason(self, rec: RobotRecord) -> str | None:
        """Why an operator holds the robot still (as it reports, or as asked), or None."""
        state = rec.state
        if rec.status in OPERATOR_HELD and state is not None:
            return state.detail or state.mode.value
        hold = self._desk.hold(rec.robot_id)
        if hold.restrictive is None:
            return None
        why = "emergency stop" if hold.estop else "paused"
        given = self._desk.reason(rec.robot_id)
        return f"{why} by the operator" + (f": {given}" if given else "")

    def _sync_hold(self, rec: RobotRecord, now: float, wall: float) -> tuple[Effects, bool]:
        """Make the ledger's operator hold of the robot match what is asked and what it
        reports (call with the lock held); returns the effects and whether it was released."""
        why = self._hold_reason(rec)
        held = rec.robot_id in self._ledger.held
        if why is not None and not held:
            return self._ledger.hold_robot(rec.robot_id, why, now, wall), False
        if why is None and held:
            return self._ledger.release_robot(rec.robot_id, now, wall), True
        return [], False

    def _sync_holds(self, robot_id: str | None, now: float, wall: float) -> tuple[Effects, bool]:
        """:meth:`_sync_hold` for one robot (if known) or (``None``) every robot."""
        if robot_id is None:
            records = list(self._roster.records())
        else:
            rec = self._roster.record(robot_id)
            records = [] if rec is None else [rec]
        effects: Effects = []
        released = False
        for rec in records:
            more, freed = self._sync_hold(rec, now, wall)
            effects += more
            released |= freed
        return effects, released

    def control(
        self, action: ControlAction, robot_id: str | None = None, reason: str | None = None
    ) -> ControlCommand:
        """Pause, resume, e-stop or release one robot or (``None``) the whole fleet.

        The command is published first, in a batch of its own (answered once it is sent);
        paused and e-stopped robots keep their tasks (no timeout, not stuck) and take no new
        ones; on resume the planner plans them again. Raises :class:`RobotNotFound`.
        """
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            if robot_id is not None and not self._roster.known(robot_id):
                raise RobotNotFound(f"robot {robot_id} not found")
            message = self._desk.command(action, robot_id, reason, wall)
            sent = self._outbox.enqueue([Publish(message)])
            effects, released = self._sync_holds(robot_id, now, wall)
            self._queue([*effects, self._operator_saved()], now)
        self._counters.add("control_requests")
        if action is ControlAction.ESTOP:
            self._counters.add("estops_requested")
        self._settle(sent, wait=True)
        if released:
            self._planner.request("resumed")
        return message

    def on_control(self, command: ControlCommand) -> None:
        """An operator command seen on the control keys: one another tool issued (e.g.
        ``parkfleet estop`` from another process) is taken up as if asked here -- robots
        held or released, the record stored -- so the service re-sends a latched e-stop to
        robots that join later, and never re-asserts one that was released elsewhere."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            if self._closed or not self._desk.adopt(command):
                return
            effects, released = self._sync_holds(command.robot_id, now, wall)
            batch = self._queue([*effects, self._operator_saved()], now)
        self._counters.add("control_adopted")
        self._settle(batch)
        if released:
            self._planner.request("resumed")

    def control_state(self) -> ControlState:
        """What the operator asked: the fleet-wide hold, robots with a command of their own."""
        with self._lock:
            return self._desk.state()

    def _set_in_service(self, robot_id: str, in_service: bool) -> RobotView:
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            rec = self._roster.record(robot_id)
            view = None if rec is None else Roster.view_of(rec)
            if rec is None or view is None:  # no pose yet: nothing to show or plan
                raise RobotNotFound(f"robot {robot_id} not found")
            self._roster.set_in_service(robot_id, in_service)
            effects = [] if in_service else self._ledger.robot_decommissioned(robot_id, wall)
            batch = self._queue([*effects, self._operator_saved()], now)
            view = Roster.view_of(rec)
        assert view is not None
        self._outbox.emit([RobotEvent(robot=view)])
        self._settle(batch, wait=True)
        self._planner.request("commissioned" if in_service else "decommissioned")
        return view

    def decommission(self, robot_id: str) -> RobotView:
        """Take a robot out of service: it gets no task, its task under way is requeued (and
        the robot told to stop it), and once lost it no longer counts as an obstacle for
        planning and goal validation. Raises :class:`RobotNotFound`."""
        return self._set_in_service(robot_id, False)

    def commission(self, robot_id: str) -> RobotView:
        """Put a decommissioned robot back in service. Raises :class:`RobotNotFound`."""
        return self._set_in_service(robot_id, True)
