"""The state every role of the fleet service shares, and the helpers all of them use.

:class:`ServiceState` declares what :class:`~fleet.service.fleet_service.FleetService`
builds in its ``__init__`` -- one lock around the roster, the ledger and the obstacles, the
outbox, the planner worker -- so that each role (:mod:`~fleet.service.submission`,
:mod:`~fleet.service.operators`, :mod:`~fleet.service.planning`) is read on its own and
type-checked against the same attributes. Nothing here starts a thread or does I/O.
"""

from __future__ import annotations

import logging
import threading

from fleet.core.params import RobotProfile
from fleet.core.wire import (
    CancelAssignment,
    Obstacle,
)
from fleet.io.settings import Settings
from fleet.service.bus import FleetBus
from fleet.service.clock import Clock
from fleet.service.control_desk import ControlDesk
from fleet.service.effects import Effects, Publish
from fleet.service.ledger import TaskLedger
from fleet.service.outbox import Batch, Outbox
from fleet.service.planner_worker import PlannerWorker
from fleet.service.roster import RobotRecord, Roster
from fleet.service.stats import Counters
from fleet.service.store import TaskStore

_log = logging.getLogger(__name__)


class ServiceState:
    """The fleet service's shared state (built by ``FleetService.__init__``) and helpers."""

    settings: Settings
    lead_time_max: float  # bound of the planning lead time [s, robot time]
    _bus: FleetBus
    _store: TaskStore
    _clock: Clock
    _lock: threading.RLock
    _counters: Counters
    _roster: Roster
    _ledger: TaskLedger
    _outbox: Outbox
    _planner: PlannerWorker
    _obstacles: list[Obstacle]
    _desk: ControlDesk  # what the operator asked (pause, e-stop), held to
    _keys_in_flight: dict[str, threading.Event]  # idempotency keys being stored
    _obstacles_version: int  # rises with every set_obstacles
    _time_scale: float | None  # robot seconds per service second
    _close_pairs: set[tuple[str, str]]
    _inline: bool  # no threads: effects and plans run on the calling thread
    _closed: bool

    def _holds_lock(self) -> bool:
        """Whether the calling thread holds the service lock (the outbox asserts it does not)."""
        return bool(self._lock._is_owned())  # type: ignore[attr-defined]

    def _queue(self, effects: Effects, now: float) -> Batch | None:
        """Queue a transition's effects (call with the lock held: keeps their order)."""
        if not effects:
            return None
        for e in effects:  # remember cancels, so a robot driving on is told again later
            if isinstance(e, Publish) and isinstance(e.message, CancelAssignment):
                rec = self._roster.record(e.message.robot_id)
                if rec is not None:
                    rec.cancel_at = now
        return self._outbox.enqueue(effects)

    def _snapshot_version(self) -> int:
        """The version of everything a plan depends on (call with the lock held): owned by
        the structures that change -- the roster, the ledger, the obstacles -- each rising
        with its own changes (poses excepted), so a plan whose snapshot had another version
        is stale."""
        return self._roster.version + self._ledger.version + self._obstacles_version

    def _settle(self, batch: Batch | None = None, wait: bool = False) -> None:
        """After releasing the lock: apply queued effects here (no threads), or wait until
        ``batch`` is applied (``wait``: the caller answers only once it is stored)."""
        if self._inline:
            self._outbox.run_pending()
        elif wait:
            self._outbox.wait(batch)

    def _profile_of(self, robot_id: str | None) -> RobotProfile:
        """The robot's own profile (its description), else the host's ``[profile]``."""
        if robot_id is None:
            return self.settings.profile
        return self._roster.profile_of(robot_id, self.settings.profile)

    def _available(self, rec: RobotRecord | None) -> bool:
        """Whether the robot may take a new task: known pose, not lost, in service, not held
        still by an operator, no task under way, and not described as unable to reverse
        (laws (17)/(20) reverse near the goal: the fleet never assigns such a robot)."""
        return (
            rec is not None
            and rec.state is not None
            and (rec.description is None or rec.description.may_reverse)
            and rec.token is not False
            and rec.in_service
            and rec.robot_id not in self._ledger.robot_task
            and rec.robot_id not in self._ledger.held
        )
