"""The fleet service shell: API calls and bus callbacks around the ledger, roster and planner.

One class, :class:`FleetService`, in roles of one module each (its public interface is the
union): :mod:`~fleet.service.submission` (submit, bays, cancel),
:mod:`~fleet.service.operators` (pause/resume/e-stop, commission),
:mod:`~fleet.service.planning` (snapshot, apply, proximity trigger), on the shared state
declared in :mod:`~fleet.service.service_state`. This module keeps its life (threads), the
bus callbacks, the tick and sweeps, and the queries.

:class:`FleetService` owns one lock (``_lock``) around the in-memory state only -- the
roster (:mod:`~fleet.service.roster`), the task ledger (:mod:`~fleet.service.ledger`), the
obstacles -- and never writes the store or publishes while holding it: transitions return
effects, which are queued in the outbox under the lock (keeping their order) and applied
after it is released, stored before announced (:mod:`~fleet.service.outbox`).

Threads (``start()``):

* bus callbacks (:meth:`~FleetService.on_state` at the robots' 50 Hz,
  :meth:`~FleetService.on_robot_alive`, :meth:`~FleetService.on_robot_gone`) and API calls;
* ``fleet-tick`` every ``TICK_INTERVAL_S``: timeouts, re-sends, the proximity trigger of the
  planner, the periodic sweeps (lost robots, finished tasks);
* ``fleet-planner`` (:mod:`~fleet.service.planner_worker`): snapshot -> plan -> apply, with
  no lock held while it plans: the tick never waits for it;
* ``fleet-effects`` (the outbox): store writes, then publishes, then listener calls.

``start(background=False)`` starts none of them: the caller drives :meth:`tick`, which then
also plans when asked to and applies effects on the calling thread (unit tests, with a
:class:`~fleet.service.clock.FakeClock`).

Time: one injected :class:`~fleet.service.clock.Clock`; every deadline (timeouts, re-sends,
event throttling, rate measurement, retention of lost robots, pacing) runs on its monotonic
reading, wall time only stamps stored tasks, robot views and path samples.

Dispatch is asynchronous: :meth:`submit` validates the goal and reserves it under the lock,
writes the task *without* the lock -- so concurrent submits share one commit of the store
(group commit) and the answer is sent only after it -- and adds it to the ledger (where the
planner sees it) only once it is stored. Planning re-runs as the yard changes (see
:mod:`~fleet.service.planner_worker`): tasks arrive or finish, robots join, are lost or are
removed, a robot leaves its predicted corridor by more than ``replan_corridor_m``, two robots
come closer than ``safety_separation_m + replan_separation_margin_m``, and every
``replan_period_s``. Only decisions that change something are stored and sent.

Operators (docs/operating.md): :meth:`~FleetService.control` pauses, resumes,
e-stops or releases robots -- the command is published through the outbox in a batch of
its own (never delayed by a store write), the :class:`~fleet.service.control_desk.ControlDesk`
remembers it and :meth:`~FleetService.on_state` re-sends it to a robot that does not obey;
a robot held still (as asked, or as it reports) is an operator hold in the ledger (no
timeout, not stuck, standing for the planner, no new task). :meth:`~FleetService.decommission`
takes a robot out of service (roster state: no task, its task requeued, once lost no
obstacle). :meth:`~FleetService.submit_to_bay` submits to a named bay of the site map
(reserved under the lock, released by the ledger when the task ends). Stuck robots are
found and recovered on the tick (:meth:`~fleet.service.ledger.TaskLedger.recover_stuck`),
with the cause the roster shows (:func:`~fleet.service.stuck.stuck_cause`).

Bounded by design: recorded paths (:mod:`~fleet.service.paths`); lost robots are removed
``lost_robot_retention_s`` after they were lost, or by an operator (:meth:`remove_robot`),
and everything kept per robot goes with them (:class:`~fleet.service.roster.RobotRecord`);
finished tasks are deleted from the store ``finished_task_retention_s`` after they ended.
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
from collections.abc import Callable
from types import TracebackType

from fleet.core.planner import plan
from fleet.core.planner.clusters import components
from fleet.core.tasks import (
    RobotConflict,
    RobotEvent,
    RobotNotFound,
    RobotView,
    Task,
    TaskNotFound,
    TaskStatus,
)
from fleet.core.wire import (
    CancelAssignment,
    Obstacle,
    ObstacleSet,
    RobotDescription,
    RobotState,
)
from fleet.io.settings import Settings
from fleet.service.bus import FleetBus
from fleet.service.clock import Clock, SystemClock
from fleet.service.control_desk import ControlDesk
from fleet.service.effects import Publish, PurgeFinished
from fleet.service.ledger import RESEND_INTERVAL_S, TaskLedger, ledger_config
from fleet.service.operators import OperatorControls
from fleet.service.outbox import Batch, Listener, Outbox
from fleet.service.paths import PathSample
from fleet.service.planner_process import PlannerProcess
from fleet.service.planner_worker import PlanFunction, PlannerWorker
from fleet.service.planning import PlannerGlue
from fleet.service.roster import RobotRecord, Roster
from fleet.service.stats import Counters
from fleet.service.store import TaskStore
from fleet.service.stuck import stuck_cause
from fleet.service.submission import Submission
from fleet.service.zones import ZoneState, fleet_zones, zone_bodies

_log = logging.getLogger(__name__)

#: Period of the tick thread [s].
TICK_INTERVAL_S = RESEND_INTERVAL_S / 2
#: Minimum interval of pose-only robot events per robot [s] (status changes are immediate).
ROBOT_EVENT_INTERVAL_S = 0.1
#: Bound of the planning lead time [s, robot time] (see :meth:`FleetService._lead_time`).
LEAD_TIME_MAX_S = 10.0
#: Window over which a robot's control rate is measured [s, monotonic].
RATE_WINDOW_S = 2.0
#: How often lost robots are checked for retention, and finished tasks purged [s].
ROBOT_SWEEP_INTERVAL_S = 1.0
TASK_SWEEP_INTERVAL_S = 60.0
#: Finished tasks deleted per purge (one bounded transaction each).
TASK_PURGE_BATCH = 1000


class FleetService(Submission, OperatorControls, PlannerGlue):
    """Assigns parking tasks to robots and chooses cw/ccw; see the module docstring."""

    def __init__(
        self,
        settings: Settings,
        bus: FleetBus,
        store: TaskStore,
        clock: Clock | None = None,
        planner: PlanFunction | None = None,
    ) -> None:
        self.settings = settings
        self._bus = bus
        self._store = store
        self._clock: Clock = clock if clock is not None else SystemClock()
        self._lock = threading.RLock()
        self._counters = Counters()
        peer_radius = max(settings.avoidance.peer_radius, 0.1)
        self._roster = Roster(parked_cell=peer_radius)
        self._ledger = TaskLedger(
            ledger_config(settings),
            site=settings.site,
        )
        self._outbox = Outbox(store, bus, self._counters, self._holds_lock)
        #: The planner's own process, when it plans there (fleet.service.host opens it):
        #: its restarts count among the service's counters.
        self._planner_process = planner if isinstance(planner, PlannerProcess) else None
        if self._planner_process is not None:
            self._planner_process.counters = self._counters
        self._planner = PlannerWorker(
            self._take_snapshot,
            planner if planner is not None else plan,
            self._apply_plan,
            self._clock,
            self._counters,
            period_s=settings.replan_period_s,
        )
        site = settings.site  # the site map's obstacles are the initial ones (PUT replaces)
        self._obstacles: list[Obstacle] = [] if site is None else site.static_obstacles()
        self._ledger.zones.set_zones(
            fleet_zones(settings, self._obstacles), zone_bodies(settings, self._obstacles)
        )
        self._desk = ControlDesk()  # what the operator asked (pause, e-stop), held to
        self._keys_in_flight: dict[str, threading.Event] = {}  # idempotency keys being stored
        self._obstacles_version = 0  # rises with every set_obstacles
        self._time_scale: float | None = None  # robot seconds per service second
        self._close_pairs: set[tuple[str, str]] = set()
        self._next_robot_sweep = -float("inf")  # [s, monotonic]
        self._next_task_sweep = -float("inf")
        self.lead_time_max = LEAD_TIME_MAX_S
        self._inline = True  # no threads: effects and plans run on the calling thread
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._started = False
        self._closed = False

    # -- life --------------------------------------------------------------------------

    def start(self, background: bool = True) -> None:
        """Recover unfinished tasks from the store, start the bus and the threads.

        ``background=False`` starts no thread: the caller drives :meth:`tick` (unit tests).
        Recovered ``assigned``/``driving``/``waiting`` tasks keep their robot and law; their
        assignment is re-sent until acknowledged and their timeout restarts now. Recovered
        ``queued`` tasks are planned as usual.
        """
        unfinished = self._store.unfinished()
        operator = self._stored_operator_record()
        with self._lock:
            if self._started:
                return
            self._started = True
            self._inline = not background
            n = self._ledger.recover(unfinished, self._clock.monotonic())
            if operator is not None:
                self._desk.restore(operator.control_state())
                self._roster.restore_out_of_service(operator.out_of_service)
        self._counters.add("tasks_recovered", n)
        self._bus.start(self)
        if background:
            self._outbox.start()
            self._planner.start()
            self._thread = threading.Thread(target=self._run, name="fleet-tick", daemon=True)
            self._thread.start()
        if n:
            self._planner.request("recovered")

    def close(self) -> None:
        """Stop the threads and the bus, after applying the effects already queued;
        idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=10.0)
        self._planner.close()
        self._outbox.close()
        self._bus.close()

    def __enter__(self) -> FleetService:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _run(self) -> None:
        while not self._stop.wait(TICK_INTERVAL_S):
            try:
                self.tick()
            except Exception:
                self._counters.add("tick_errors")
                _log.exception("fleet service tick failed")

    def add_listener(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener`` on every event (from service threads, without the lock held).

        Returns a function that unsubscribes it.
        """
        return self._outbox.add_listener(listener)

    # -- bus callbacks -------------------------------------------------------------------

    def on_state(self, state: RobotState) -> None:
        """A robot's state: roster, operator commands it does not obey (re-sent),
        acknowledgement, arrival, path, progress, corridor, operator holds (hot path: O(1)
        under the lock; a robot event at most every ``ROBOT_EVENT_INTERVAL_S``)."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        view: RobotView | None = None
        batch: Batch | None = None
        ask_store = released = False
        with self._lock:
            if self._closed:
                return
            resend = self._desk.check(state, now, wall)
            if resend is not None:  # first: an e-stop waits for no store write
                batch = self._outbox.enqueue([Publish(resend)])
            known = self._roster.record(state.robot_id)
            joined = known is None or known.state is None
            rec, changed = self._roster.update(state, now, wall)
            if now - rec.rate_at >= RATE_WINDOW_S or state.seq < rec.rate_seq:
                self._measure_rate(rec, state, now)
            seen = self._ledger.observe(state, now, wall)
            if seen.effects:
                batch = self._queue(seen.effects, now)
            if changed:  # its mode changed: maybe paused or e-stopped, or no more
                hold_effects, released = self._sync_hold(rec, now, wall)
                batch = self._queue(hold_effects, now) or batch
            if seen.stray and now - rec.cancel_at >= RESEND_INTERVAL_S:
                rec.cancel_at = now  # at most one cancel (or store read) per interval
                stop = self._stop_stray(rec, state)
                ask_store = stop is None
                batch = stop or batch
            if changed or now - rec.event_at >= ROBOT_EVENT_INTERVAL_S:
                rec.event_at = now
                view = Roster.view_of(rec)
        if view is not None:
            self._outbox.emit([RobotEvent(robot=view)])
        if batch is not None:
            self._settle()
        if ask_store:
            self._stop_stray_stored(state)
        if resend is not None:
            self._counters.add("control_resent")
        if released:
            self._planner.request("resumed")
        if seen.finished:
            self._planner.request("task_finished")
        elif seen.off_corridor:
            self._planner.request("corridor")
        elif seen.zones_changed:
            self._planner.request("zones")
        elif joined:
            self._planner.request("robot_joined")

    def _measure_rate(self, rec: RobotRecord, state: RobotState, now: float) -> None:
        """Robot seconds per service second, from state sequence numbers (a time-scaled
        simulation runs faster than the service clock; a real robot at 1)."""
        if rec.rate_seq < 0 or state.seq < rec.rate_seq:  # first state, or a restart
            rec.rate_seq, rec.rate_at = state.seq, now
            return
        scale = (state.seq - rec.rate_seq) / self.settings.control_rate_hz / (now - rec.rate_at)
        self._time_scale = scale if self._time_scale is None else max(self._time_scale, scale)
        rec.rate_seq, rec.rate_at = state.seq, now
        # The receding horizon's period is robot time, as the stuck and standoff windows
        # are: a simulation at 5x is planned for as often as real robots would be (never
        # less often than ``replan_period_s`` of the service's time).
        self._planner.period_s = self.settings.replan_period_s / max(self._time_scale, 1.0)

    def _stop_stray(self, rec: RobotRecord, state: RobotState) -> Batch | None:
        """The robot drives a task that is not active: cancel it if it is known finished
        (a cancel or a timeout's stop re-sent until obeyed, or a late duplicate of a
        cancelled assignment). Unknown here: :meth:`_stop_stray_stored` asks the store."""
        assert state.task_id is not None
        if self._ledger.finished_status(state.task_id) is None:
            return None
        self._counters.add("cancels_resent")
        cancel = CancelAssignment(robot_id=rec.robot_id, task_id=state.task_id)
        return self._outbox.enqueue([Publish(cancel)])

    def _stop_stray_stored(self, state: RobotState) -> None:
        """Same as :meth:`_stop_stray` for a task finished long ago (or before a restart):
        one store read, outside the lock, at most once per re-send interval per robot."""
        assert state.task_id is not None
        stored = self._store.get(state.task_id)
        if stored is not None and stored.status.final:
            self._counters.add("cancels_resent")
            cancel = CancelAssignment(robot_id=state.robot_id, task_id=state.task_id)
            self._outbox.enqueue([Publish(cancel)])
            self._settle()

    def on_robot_alive(self, robot_id: str) -> None:
        """A robot's liveliness token appeared."""
        with self._lock:
            if self._closed:
                return
            rec = self._roster.alive(robot_id, self._clock.wall())
            view = Roster.view_of(rec)
        if view is not None:
            self._outbox.emit([RobotEvent(robot=view)])
        self._planner.request("robot_joined")

    def on_description(self, description: RobotDescription) -> None:
        """A robot said what it is: kept in the roster; the planner uses its profile."""
        with self._lock:
            if self._closed:
                return
            rec, changed = self._roster.describe(description)
            if not changed:
                return
            view = Roster.view_of(rec)
        self._counters.add("robots_described")
        if view is not None:
            self._outbox.emit([RobotEvent(robot=view)])
        self._planner.request("robot_described")

    def on_robot_gone(self, robot_id: str) -> None:
        """A robot's token disappeared: it is lost; its task fails or is requeued."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            if self._closed:
                return
            rec = self._roster.gone(robot_id, now)
            view = Roster.view_of(rec)
            batch = self._queue(self._ledger.robot_lost(robot_id, now, wall), now)
        self._counters.add("robots_lost")
        if view is not None:
            self._outbox.emit([RobotEvent(robot=view)])
        self._settle(batch)
        self._planner.request("robot_lost")

    # -- background work -----------------------------------------------------------------

    def tick(self) -> None:
        """One step: timeouts, re-sends of unacknowledged assignments, the proximity
        trigger, the periodic sweeps; without threads also planning, when due."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            if self._closed:
                return
            timeouts = self._ledger.timeouts(now, wall)
            self._queue(timeouts, now)
            stuck, recovered = self._recover_stuck(now, wall)
            standoffs, early = self._break_standoffs(now, wall)
            stuck, recovered = stuck + early, recovered + early
            resends = self._ledger.resends(now)
            self._outbox.enqueue(resends)
            points = self._positions()
            removed = self._sweep_robots(now, wall) if now >= self._next_robot_sweep else []
            purge = now >= self._next_task_sweep
            if purge:
                self._next_task_sweep = now + TASK_SWEEP_INTERVAL_S
                before = wall - self.settings.finished_task_retention_s
                self._outbox.enqueue([PurgeFinished(before, TASK_PURGE_BATCH)])
        if resends:
            self._counters.add("assignments_resent", len(resends))
        if removed:
            self._counters.add("robots_expired", len(removed))
            _log.info("removed robots lost for too long: %s", ", ".join(removed))
        self._settle()
        if timeouts:
            self._planner.request("task_finished")
        if stuck:
            self._counters.add("stuck", stuck)
            self._counters.add("recoveries", recovered)
            self._planner.request("stuck")
        if standoffs:
            self._counters.add("standoffs_broken", len(standoffs))
            _log.info("standoffs broken: %s", "; ".join(standoffs))
            self._planner.request("standoff")
        if removed:
            self._planner.request("robot_removed")
        self._check_separation(points)
        if self._inline:
            self._planner.period_due()
            self._planner.step()
            self._settle()

    def _recover_stuck(self, now: float, wall: float) -> tuple[int, int]:
        """The next recovery of every stuck task, with the cause the roster shows (call
        with the lock held); returns (stuck tasks, recoveries tried: the others failed)."""
        stuck = self._ledger.stuck(now)
        recovered = 0
        for task in stuck:
            self._recover(task, now, wall)
            recovered += task.id in self._ledger.active
        return len(stuck), recovered

    def _recover(self, task: Task, now: float, wall: float) -> None:
        """The task's next stuck recovery, with the cause the roster shows (lock held)."""
        cause = self._stuck_cause(task, now)
        by_post, alone = self._by_post(task), self._alone(task)
        self._queue(self._ledger.recover_stuck(task.id, cause, now, wall, by_post, alone), now)

    def _where(self, task: Task) -> tuple[float, float] | None:
        """Where the task's robot last said it was [m] (None: unknown)."""
        rec = None if task.robot_id is None else self._roster.record(task.robot_id)
        return None if rec is None or rec.state is None else (rec.state.pose.x, rec.state.pose.y)

    def _by_post(self, task: Task) -> bool:
        """Whether the task's robot stands within a post's Eq. (27) influence radius."""
        at = self._where(task)
        return at is not None and any(
            o.end is None and o.distance(*at) <= o.radius for o in self._obstacles
        )

    def _alone(self, task: Task) -> bool:
        """Whether no other robot is within the peer radius of the task's robot."""
        at = self._where(task)
        radius = self.settings.avoidance.peer_radius
        return at is None or self._nearest_robot(task.robot_id or "", at, radius) is None

    def _break_standoffs(self, now: float, wall: float) -> tuple[list[str], int]:
        """Break every standoff (call with the lock held): the robots in one (within the
        peer radius of each other) are a group, the one with the youngest task gives way
        (unless the robot it is held off by is held by the plan for a zone it holds: that
        one stands aside, the plans route the group round it; or stands with no task: the
        plans route it round that robot -- once per robot, a second standoff is broken the
        usual way) and the others' windows restart; returns what was done, one line per
        standoff, and how many stuck recoveries it began. A robot alone (no robot within
        the peer radius: held by an obstacle's repulsion or body) is stuck, not in a
        standoff: within a post's influence radius it gets its first stuck recovery (flip,
        routed round the posts' zones: two posts' terms can hold it in a gap's mouth for
        good) once it has stalled ``post_stall_after_s`` -- no peer there will move away
        --, the others after the stuck watch's whole window."""
        early = self._recover_post_stalls(now, wall)
        tasks = self._ledger.standoffs()
        if not tasks:
            return [], early
        radius = self.settings.avoidance.peer_radius
        where: dict[str, tuple[float, float]] = {}
        for task in tasks:
            at = self._where(task)
            if at is not None:
                where[task.id] = at
        tasks = [t for t in tasks if t.id in where]
        links = [
            (i, j)
            for i, j in itertools.combinations(range(len(tasks)), 2)
            if math.dist(where[tasks[i].id], where[tasks[j].id]) <= radius
        ]
        done: list[str] = []
        for members in components(len(tasks), links):
            group = [tasks[i] for i in members]
            gives = max(group, key=lambda t: (t.created_at, t.robot_id or ""))
            assert gives.robot_id is not None
            nearest = self._nearest_robot(gives.robot_id, where[gives.id], radius)
            cause = None if nearest is None else self._standoff_words(nearest)
            blocker = None if nearest is None else self._ledger.task_of_robot(nearest[1])
            if (
                cause is not None
                and blocker is not None
                and self._ledger.stands_aside(blocker, gives.robot_id)
            ):
                # the robot it waits on is held by the plan for a zone it holds: giving
                # way would wait for a robot that waits for it
                for other in group:
                    self._ledger.stuck_watch.restart(other.id)
                done.append(f"{gives.robot_id} goes round {blocker.robot_id}, held ({cause})")
                continue
            if (
                nearest is not None
                and blocker is None
                and self._ledger.goes_round(gives.id, nearest[1])
            ):
                # the robot it is held off by stands (no task): giving way changes nothing
                for other in group:
                    self._ledger.stuck_watch.restart(other.id)
                done.append(f"{gives.robot_id} goes round {nearest[1]}, standing ({cause})")
                continue
            if cause is None:  # alone (by an obstacle): stuck, not a standoff
                if self._ledger.stuck_watch.attempts(gives.id) == 0 and self._by_post(gives):
                    self._recover(gives, now, wall)
                    early += 1
                else:
                    self._ledger.stuck_watch.restart(gives.id)
                continue
            self._queue(self._ledger.break_standoff(gives.id, cause, now, wall), now)
            for other in group:
                if other is not gives:
                    self._ledger.stuck_watch.restart(other.id)
            done.append(f"{gives.robot_id} gives way ({cause})")
        return done, early

    def _nearest_robot(
        self, robot_id: str, at: tuple[float, float], radius: float
    ) -> tuple[float, str] | None:
        """(distance [m], id) of the robot nearest ``robot_id`` (at ``at``) within
        ``radius`` [m]; None: no robot is that near."""
        near = []
        for rec in self._roster.records():
            s = rec.state
            if rec.robot_id == robot_id or s is None or rec.gone_for_good:
                continue
            d = math.hypot(s.pose.x - at[0], s.pose.y - at[1])
            if d <= radius:
                near.append((d, rec.robot_id))
        return min(near) if near else None

    def _recover_post_stalls(self, now: float, wall: float) -> int:
        """The first stuck recovery of every robot alone by a post that has stalled
        ``post_stall_after_s`` (call with the lock held); returns how many began."""
        began = 0
        for task in self._ledger.standoffs(self.settings.post_stall_after_s):
            watch = self._ledger.stuck_watch
            if watch.attempts(task.id) == 0 and self._by_post(task) and self._alone(task):
                self._recover(task, now, wall)
                began += 1
        return began

    def _standoff_words(self, nearest: tuple[float, str]) -> str:
        """A standoff's cause as words: the nearest robot (distance [m], id)."""
        d, other = nearest
        seconds = self.settings.standoff_after_s
        return f"no progress for {seconds:g} s while avoiding {other} at {d:.2f} m"

    def _stuck_cause(self, task: Task, now: float) -> str:
        """What the service sees around a stuck task's robot: the peers near it (robots
        taken out of the yard excepted), the obstacles, whether it is heard."""
        assert task.robot_id is not None
        rec = self._roster.record(task.robot_id)
        robot = None if rec is None else Roster.view_of(rec)
        radius = self.settings.avoidance.peer_radius
        peers = []
        if robot is not None:
            x, y = robot.pose.x, robot.pose.y
            for other in self._roster.records():
                s = other.state
                if (
                    s is not None
                    and not other.gone_for_good
                    and abs(s.pose.x - x) <= radius
                    and abs(s.pose.y - y) <= radius
                ):
                    view = Roster.view_of(other)
                    if view is not None:
                        peers.append(view)
        return stuck_cause(
            robot,
            self._ledger.silent(task.id, now),
            peers,
            self._obstacles,
            radius,
            self.settings.stuck_after_s,
        )

    def _sweep_robots(self, now: float, wall: float) -> list[str]:
        """Remove robots lost for ``lost_robot_retention_s`` (call with the lock held)."""
        self._next_robot_sweep = now + ROBOT_SWEEP_INTERVAL_S
        removed = []
        for rid in self._roster.expired(now, self.settings.lost_robot_retention_s):
            if rid in self._ledger.robot_task:
                continue  # a silent robot still holding a task: its timeout comes first
            self._forget_robot(rid, now, wall)
            removed.append(rid)
        return removed

    def _forget_robot(self, robot_id: str, now: float, wall: float) -> Batch | None:
        """Remove a robot and everything kept about it (call with the lock held): queued
        tasks naming it fail; the operator record is stored again if it named the robot."""
        effects = self._ledger.robot_removed(robot_id, wall)
        rec = self._roster.remove(robot_id)
        named = robot_id in self._desk.state().robots or (rec is not None and not rec.in_service)
        self._desk.forget(robot_id)
        if named:
            effects.append(self._operator_saved())
        return self._queue(effects, now)

    # -- queries and yard ---------------------------------------------------------------

    def task(self, task_id: str) -> Task:
        with self._lock:
            active = self._ledger.get(task_id)
        if active is not None:
            return active
        stored = self._store.get(task_id)
        if stored is None:
            raise TaskNotFound(f"task {task_id} not found")
        return stored

    def history(self, task_id: str) -> list[tuple[float, str, Task]]:
        """Every stored transition of a task, oldest first: (time [s since epoch], event
        such as ``assigned`` or ``recovery``, the task as stored then); read from the store,
        so a transition shows once it is stored."""
        rows = self._store.history(task_id)
        if not rows and self._store.get(task_id) is None:
            raise TaskNotFound(f"task {task_id} not found")
        return rows

    def tasks(self, status: TaskStatus | None = None, robot_id: str | None = None) -> list[Task]:
        """Tasks in creation order, optionally filtered (read from the store)."""
        return self._store.list(status=status, robot_id=robot_id)

    def robots(self) -> list[RobotView]:
        with self._lock:
            return self._roster.views()

    def robot(self, robot_id: str) -> RobotView:
        with self._lock:
            view = self._roster.view(robot_id)
        if view is None:
            raise RobotNotFound(f"robot {robot_id} not found")
        return view

    def remove_robot(self, robot_id: str) -> None:
        """Forget a lost robot (an operator took it out of the yard): it stops being an
        obstacle, queued tasks naming it fail. :class:`RobotNotFound`, or
        :class:`RobotConflict` while its liveliness token is present or it has a task."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            rec = self._roster.record(robot_id)
            if rec is None:
                raise RobotNotFound(f"robot {robot_id} not found")
            if rec.token is True:
                raise RobotConflict(
                    f"robot {robot_id} is connected (its liveliness token is present); "
                    "only a lost robot can be removed"
                )
            task = self._ledger.task_of_robot(robot_id)
            if task is not None:
                raise RobotConflict(
                    f"robot {robot_id} still has task {task.id} ({task.status.value})"
                )
            batch = self._forget_robot(robot_id, now, wall)
        self._counters.add("robots_removed")
        self._settle(batch, wait=True)
        self._planner.request("robot_removed")

    def obstacles(self) -> list[Obstacle]:
        with self._lock:
            return list(self._obstacles)

    def last_states(self) -> list[tuple[RobotState, float]]:
        """The last state of every robot still in the yard (not lost and decommissioned),
        with how long ago it was heard [s]: what the bus replays to a robot entering its
        cell (fleet/core/wire.py, "Replay of last states"). Every one, not only the
        silent: a robot that fell silent a moment ago publishes nothing more a newcomer
        could hear, and a live robot's stream is newer than its replay and wins."""
        now = self._clock.monotonic()
        with self._lock:
            return [
                (rec.state, now - rec.seen)
                for rec in self._roster.records()
                if rec.state is not None and not rec.gone_for_good
            ]

    def set_obstacles(self, obstacles: list[Obstacle]) -> None:
        """Replace the static obstacles and publish them (``ObstacleSet``); the narrow
        passages they make are found again."""
        msg = ObstacleSet(obstacles=list(obstacles))
        zones = fleet_zones(self.settings, msg.obstacles)
        with self._lock:
            self._obstacles = list(msg.obstacles)
            self._ledger.zones.set_zones(zones, zone_bodies(self.settings, msg.obstacles))
            self._obstacles_version += 1
            batch = self._queue([Publish(msg)], self._clock.monotonic())
        self._settle(batch, wait=True)
        self._planner.request("obstacles")

    def zones(self) -> list[ZoneState]:
        """Every single-robot zone with the robots holding it (and their tasks)."""
        with self._lock:
            book, tasks = self._ledger.zones, self._ledger.robot_task
            out = []
            for z in book.shapes:
                robots = book.holding(z.name)
                out.append(
                    ZoneState(
                        z, robots, tuple(t for r in robots if (t := tasks.get(r)) is not None)
                    )
                )
            return out

    def path(self, task_id: str) -> list[PathSample]:
        """Recorded (t [s since epoch], x [m], y [m], theta [rad], u [m/s], omega [rad/s])
        of the task's robot while it ran the task (downsampled when long; empty once
        evicted)."""
        with self._lock:
            path = self._ledger.paths.get(task_id)
            known = task_id in self._ledger.active
        if path is not None:
            return path
        if not known and self._store.get(task_id) is None:
            raise TaskNotFound(f"task {task_id} not found")
        return []

    @property
    def counters(self) -> dict[str, int]:
        out = self._counters.snapshot()
        for key, value in self._bus.counters.items():
            out[f"bus_{key}"] = value
        return out

    def sizes(self) -> dict[str, int]:
        """Entries held by each bounded structure (robots, tasks, paths, queued effects)."""
        with self._lock:
            out = self._roster.sizes() | self._ledger.sizes()
            out["close_pairs"] = len(self._close_pairs)
        out["effects_pending"] = self._outbox.pending
        return out
