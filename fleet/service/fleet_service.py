"""The fleet service: roster, task life cycle, assignment and direction choice.

Task life cycle::

    queued -> assigned (assignment published) -> driving (robot's state carries the task id)
           -> succeeded (robot reports ``arrived`` with the task id)
            | failed (timeout after ``Settings.task_timeout_s`` from assignment; robot lost
                      with ``Settings.on_robot_lost == "fail"``)
            | cancelled
    assigned/driving -> queued again when the robot is lost and ``on_robot_lost == "requeue"``

Re-planning under way: each dispatch rolls out the robots already driving an ``auto`` task
together with the new ones (``fleet.core.direction``). When flipping some of them is strictly
safer than keeping their laws, their tasks get the new law and ``revision + 1`` (stored,
then announced: event ``replanned``) and the robots get a ``ParkAssignment`` with that
revision, re-sent until a state reports it. The rollouts start from the poses the robots
are predicted to have when the plan reaches them (``Scene.lead_time``: the last planning
time, converted to robot time by the robots' observed control rate, at most
``LEAD_TIME_MAX_S``).

Every transition is saved in the :class:`~fleet.service.store.TaskStore` before it is announced.

Threads: bus callbacks (``on_state``, ``on_robot_alive``, ``on_robot_gone``), API calls and
the tick thread all share one lock (``_lock``) around the in-memory state; the store has
its own. Listeners are called *after* the lock is released, on the calling thread, so they
may call back into the service. Dispatch (optimal assignment + direction rollouts, which
take a while) runs under a separate ``_dispatch_lock`` and releases ``_lock`` while it
computes: it snapshots, plans, then re-checks and applies.

Dispatch is asynchronous: :meth:`FleetService.submit` stores the task (``queued``) and
wakes the tick thread, which assigns it. ``submit`` validates the goal and reserves it
(``GoalIndex``, a grid of the active goals) under ``_lock``, then writes the task *without*
the lock, so concurrent submits share one commit of the store (group commit), and adds it
to the in-memory state (where dispatch sees it) only once it is stored. The in-memory
state keeps indexes of the active tasks (queued, under way, task of each robot), so a
submit, a state message or a tick costs O(robots + tasks under way), not O(all tasks).
Unit tests drive :meth:`FleetService.tick` with a fake clock instead of starting the thread.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections import Counter, OrderedDict, deque
from collections.abc import Callable
from types import TracebackType

from fleet.core.assignment import TaskSpec, optimal_assignment, predicted_times
from fleet.core.direction import Mover, Scene, choose_directions
from fleet.core.goals import GoalIndex, Occupied, validate_goal
from fleet.core.tasks import (
    BayTaken,
    FleetEvent,
    GoalRejected,
    RobotEvent,
    RobotNotFound,
    RobotStatus,
    RobotView,
    Task,
    TaskConflict,
    TaskEvent,
    TaskNotFound,
    TaskRequest,
    TaskStatus,
)
from fleet.core.types import LAWS, Law
from fleet.core.wire import (
    CancelAssignment,
    ControlAction,
    ControlCommand,
    Obstacle,
    ObstacleSet,
    ParkAssignment,
    Pose,
    RobotMode,
    RobotState,
)
from fleet.io.settings import Settings
from fleet.service.bays import BayBook, BayState
from fleet.service.bus import FleetBus
from fleet.service.control_desk import ControlDesk
from fleet.service.roster import Roster
from fleet.service.store import TaskStore
from fleet.service.stuck import RECOVERIES, StuckWatch, stuck_cause

_log = logging.getLogger(__name__)

#: Seconds between re-sends of an unacknowledged assignment (and of a cancel).
RESEND_INTERVAL_S = 0.2
#: A burst of submissions is planned together once none came for this long [s, wall]
#: (at most DISPATCH_SETTLE_MAX_S of delay).
DISPATCH_SETTLE_S = 0.05
DISPATCH_SETTLE_MAX_S = 0.5
#: Samples kept per task path, and number of task paths kept.
PATH_SAMPLES = 20_000
PATHS_KEPT = 256
#: Minimum interval of pose-only robot events per robot [s] (status changes are immediate).
ROBOT_EVENT_INTERVAL_S = 0.1
#: Bound of the planning lead time [s, robot time] (see the module docstring).
LEAD_TIME_MAX_S = 10.0
#: Added to the predicted time [s] of giving a stuck task back to the robot it left.
AVOID_COST_S = 1e6
#: Window over which a robot's control rate is measured [s, service clock].
RATE_WINDOW_S = 2.0

PathSample = tuple[float, float, float, float, float, float]  # t, x, y, theta, u, omega
Listener = Callable[[FleetEvent], None]
_ACTIVE = (TaskStatus.ASSIGNED, TaskStatus.DRIVING)
#: Robots standing still with no task: their place is taken (goal validation).
_STANDING = (
    RobotStatus.ARRIVED,
    RobotStatus.HOLDING,
    RobotStatus.LOST,
    RobotStatus.PAUSED,
    RobotStatus.ESTOP,
)


class FleetService:
    """Assigns parking tasks to robots and chooses cw/ccw; see the module docstring."""

    def __init__(
        self,
        settings: Settings,
        bus: FleetBus,
        store: TaskStore,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.settings = settings
        self._bus = bus
        self._store = store
        self._clock = clock
        self._lock = threading.RLock()
        self._dispatch_lock = threading.Lock()
        self._roster = Roster()
        self._active: dict[str, Task] = {}  # every non-final task, by id
        # Indexes of _active, kept by _put/_drop so no hot path walks every task:
        self._queued: dict[str, Task] = {}  # status queued
        self._under_way: dict[str, Task] = {}  # status assigned/driving (with a robot)
        self._robot_task: dict[str, str] = {}  # robot -> its assigned/driving task
        self._claims: Counter[str] = Counter()  # robot -> active tasks naming or holding it
        self._goals = GoalIndex(max(settings.avoidance.peer_radius, 0.1))  # + pending submits
        self._keys_in_flight: dict[str, threading.Event] = {}  # idempotency keys being stored
        self._last_sent: dict[str, float] = {}
        self._deadline: dict[str, float] = {}
        self._cancel_sent: dict[str, float] = {}  # robot id -> last cancel re-sent
        self._paths: OrderedDict[str, deque[PathSample]] = OrderedDict()
        site = settings.site  # the site map's obstacles are the initial ones (PUT replaces)
        self._obstacles: list[Obstacle] = [] if site is None else list(site.obstacles)
        self._listeners: list[Listener] = []
        self._counters: Counter[str] = Counter()
        self.control_desk = ControlDesk(bus.publish_control, clock)  # operator pause / e-stop
        self._bays = BayBook(settings.site)  # bay -> the active task that reserves it
        self._decommissioned: set[str] = set()  # robots out of service (no tasks)
        self._stuck = StuckWatch(settings.stuck_after_s)  # progress of the tasks under way
        self._avoid: dict[str, str] = {}  # task -> robot it was taken from (stuck)
        self._last_robot_event: dict[str, float] = {}
        self._plan_seconds: float | None = None  # EWMA of planning wall time [s]
        self._rate_anchor: dict[str, tuple[int, float]] = {}  # robot -> (seq, time)
        self._time_scale: float | None = None  # robot seconds per service second
        self.lead_time_max = LEAD_TIME_MAX_S
        self._wake = threading.Event()
        self._last_submit = float("-inf")  # time.monotonic() of the last submit (pacing only)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._started = False
        self._closed = False

    # -- life --------------------------------------------------------------------------

    def start(self, background: bool = True) -> None:
        """Recover unfinished tasks from the store, start the bus and the tick thread.

        ``background=False`` skips the thread: the caller drives :meth:`tick` (unit tests).

        Recovered ``assigned``/``driving`` tasks keep their robot and law; their assignment
        is re-sent until acknowledged (a robot still running it acknowledges at once) and
        their timeout restarts now. Recovered ``queued`` tasks are dispatched as usual.
        """
        with self._lock:
            if self._started:
                return
            self._started = True
            self._recover(self._clock())
        self._bus.start(self)
        if background:
            self._thread = threading.Thread(target=self._run, name="fleet-tick", daemon=True)
            self._thread.start()

    def _recover(self, now: float) -> None:
        for task in self._store.unfinished():
            self._put(task)
            if task.status in _ACTIVE:
                self._deadline[task.id] = now + self.settings.task_timeout_s
                self._last_sent[task.id] = float("-inf")
            self._counters["tasks_recovered"] += 1

    def close(self) -> None:
        """Stop the tick thread and the bus; idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._stop.set()
        self._wake.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=10.0)
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
        while not self._stop.is_set():
            # Let a burst of submissions settle so its tasks are planned together (the
            # direction rollouts then see every robot about to move, not one at a time).
            settle_until = time.monotonic() + DISPATCH_SETTLE_MAX_S
            while (
                time.monotonic() - self._last_submit < DISPATCH_SETTLE_S
                and time.monotonic() < settle_until
                and not self._stop.is_set()
            ):
                time.sleep(DISPATCH_SETTLE_S / 2)
            try:
                self.tick()
            except Exception:
                self._counters["tick_errors"] += 1
                _log.exception("fleet service tick failed")
            self._wake.wait(RESEND_INTERVAL_S / 2)
            self._wake.clear()

    # -- listeners -----------------------------------------------------------------------

    def add_listener(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener`` on every event (from service threads, without the lock held).

        Returns a function that unsubscribes it.
        """
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return unsubscribe

    def _emit(self, events: list[FleetEvent]) -> None:
        if not events:
            return
        with self._lock:
            listeners = list(self._listeners)
        for event in events:
            for listener in listeners:
                try:
                    listener(event)
                except Exception:
                    self._counters["listener_errors"] += 1
                    _log.exception("fleet event listener failed")

    # -- transitions (call with _lock held) ----------------------------------------------

    def _put(self, task: Task) -> None:
        """Insert or replace a non-final task in ``_active`` and its indexes."""
        old = self._active.get(task.id)
        if old is not None:
            self._unindex(old)
        goal = task.request.goal
        self._goals.add(task.id, Occupied(goal.x, goal.y, f"the goal of task {task.id}"))
        self._bays.hold(task)
        self._active[task.id] = task
        if task.status == TaskStatus.QUEUED:
            self._queued[task.id] = task
        elif task.status in _ACTIVE and task.robot_id is not None:
            self._under_way[task.id] = task
            self._robot_task[task.robot_id] = task.id
        for rid in {task.robot_id, task.request.robot_id}:
            if rid is not None:
                self._claims[rid] += 1

    def _unindex(self, task: Task) -> None:
        self._queued.pop(task.id, None)
        self._under_way.pop(task.id, None)
        if task.robot_id is not None and self._robot_task.get(task.robot_id) == task.id:
            del self._robot_task[task.robot_id]
        for rid in {task.robot_id, task.request.robot_id}:
            if rid is not None:
                self._claims[rid] -= 1
                if self._claims[rid] <= 0:
                    del self._claims[rid]

    def _drop(self, task_id: str) -> None:
        """Remove a task that became final from ``_active`` and its indexes."""
        old = self._active.pop(task_id, None)
        if old is not None:
            self._unindex(old)
            self._bays.release(old)
        self._goals.remove(task_id)
        self._stuck.forget(task_id)
        self._avoid.pop(task_id, None)
        self._deadline.pop(task_id, None)
        self._last_sent.pop(task_id, None)

    def _transition(self, task: Task, event: str, events: list[FleetEvent]) -> None:
        """Store ``task`` (durably), update the in-memory view, queue the event."""
        self._store.save(task, event)
        if task.status.final:
            self._drop(task.id)
        else:
            self._put(task)
        events.append(TaskEvent(task=task))

    def _update(self, task: Task, now: float, **changes: object) -> Task:
        return task.model_copy(update={**changes, "updated_at": now})

    def _finish(
        self,
        task: Task,
        status: TaskStatus,
        reason: str | None,
        now: float,
        events: list[FleetEvent],
        stop_robot: bool,
    ) -> Task:
        done = self._update(task, now, status=status, reason=reason)
        self._transition(done, status.value, events)
        if stop_robot and task.robot_id is not None and task.status in _ACTIVE:
            self._cancel_sent[task.robot_id] = now
            self._bus.publish_assignment(CancelAssignment(robot_id=task.robot_id, task_id=task.id))
        return done

    def _task_of_robot(self, robot_id: str) -> Task | None:
        task_id = self._robot_task.get(robot_id)
        return None if task_id is None else self._under_way.get(task_id)

    # -- bus callbacks -------------------------------------------------------------------

    def on_state(self, state: RobotState) -> None:
        """A robot's state: roster, acknowledgement, arrival, path recording."""
        events: list[FleetEvent] = []
        with self._lock:
            if self._closed:
                return
            now = self._clock()
            view, changed = self._roster.update(state, now)
            self._measure_rate(state, now)
            task = self._task_of_robot(state.robot_id)
            if task is not None and state.task_id == task.id:
                waiting = state.mode in (RobotMode.WAITING, RobotMode.PAUSED, RobotMode.ESTOP)
                self._stuck.observe(task.id, state.pose, task.request.goal, now, waiting)
                path = self._paths.get(task.id)
                if path is not None:
                    p = state.pose
                    path.append((now, p.x, p.y, p.theta, state.u, state.omega))
                if state.mode == RobotMode.ARRIVED:
                    self._finish(task, TaskStatus.SUCCEEDED, None, now, events, False)
                elif task.status == TaskStatus.ASSIGNED:
                    self._transition(
                        self._update(task, now, status=TaskStatus.DRIVING), "acknowledged", events
                    )
            elif state.task_id is not None and state.mode in (
                RobotMode.DRIVING,
                RobotMode.AVOIDING,
            ):
                self._stop_stray(state, now)
            last = self._last_robot_event.get(state.robot_id, float("-inf"))
            if changed or now - last >= ROBOT_EVENT_INTERVAL_S:
                self._last_robot_event[state.robot_id] = now
                events.append(RobotEvent(robot=view))
        self._emit(events)
        self.control_desk.check(state)  # a robot that should be held but is not: re-send
        if events and any(isinstance(e, TaskEvent) for e in events):
            self._wake.set()

    def _measure_rate(self, state: RobotState, now: float) -> None:
        """Robot seconds per service second, from state sequence numbers (a time-scaled
        simulation runs faster than the wall clock; a real robot at 1)."""
        anchor = self._rate_anchor.get(state.robot_id)
        if anchor is None or state.seq < anchor[0]:
            self._rate_anchor[state.robot_id] = (state.seq, now)
            return
        seq0, t0 = anchor
        if now - t0 >= RATE_WINDOW_S:
            scale = (state.seq - seq0) / self.settings.control_rate_hz / (now - t0)
            self._time_scale = scale if self._time_scale is None else max(self._time_scale, scale)
            self._rate_anchor[state.robot_id] = (state.seq, now)

    def _lead_time(self) -> float:
        """Expected delay [s, robot time] until a plan reaches the robots."""
        if self._plan_seconds is None:
            return 0.0
        scale = self._time_scale if self._time_scale is not None else 1.0
        return min(self.lead_time_max, self._plan_seconds * scale)

    def _stop_stray(self, state: RobotState, now: float) -> None:
        """The robot drives a task that is not its active one: cancel it if it is finished.

        This is how a cancel (or a timeout's stop) is re-sent until the robot obeys, and how
        a robot that picked up a late duplicate of a cancelled assignment is stopped.
        """
        assert state.task_id is not None
        if now - self._cancel_sent.get(state.robot_id, float("-inf")) < RESEND_INTERVAL_S:
            return
        if state.task_id in self._active:
            return  # active but not this robot's (e.g. requeued elsewhere): leave it be
        stored = self._store.get(state.task_id)
        if stored is not None and stored.status.final:
            self._cancel_sent[state.robot_id] = now
            self._counters["cancels_resent"] += 1
            self._bus.publish_assignment(
                CancelAssignment(robot_id=state.robot_id, task_id=state.task_id)
            )

    def on_robot_alive(self, robot_id: str) -> None:
        """A robot's liveliness token appeared."""
        events: list[FleetEvent] = []
        with self._lock:
            if self._closed:
                return
            view = self._roster.alive(robot_id, self._clock())
            if view is not None:
                events.append(RobotEvent(robot=view))
        self._emit(events)
        self._wake.set()

    def on_robot_gone(self, robot_id: str) -> None:
        """A robot's token disappeared: it is lost; its task fails or is requeued."""
        events: list[FleetEvent] = []
        with self._lock:
            if self._closed:
                return
            now = self._clock()
            view = self._roster.gone(robot_id, now)
            self._counters["robots_lost"] += 1
            if view is not None:
                events.append(RobotEvent(robot=view))
            task = self._task_of_robot(robot_id)
            if task is not None:
                reason = f"robot {robot_id} lost (liveliness token gone)"
                if self.settings.on_robot_lost == "requeue":
                    self._requeue(task, now, reason + "; requeued", events)
                else:
                    self._finish(task, TaskStatus.FAILED, reason, now, events, False)
        self._emit(events)
        self._wake.set()

    def _requeue(
        self,
        task: Task,
        now: float,
        reason: str,
        events: list[FleetEvent],
        event: str = "requeued",
    ) -> None:
        """Put a task under way back in the queue (its robot keeps a named task)."""
        requeued = self._update(
            task, now, status=TaskStatus.QUEUED, robot_id=task.request.robot_id, law=None,
            reason=reason,
        )  # fmt: skip
        self._deadline.pop(task.id, None)
        self._last_sent.pop(task.id, None)
        self._transition(requeued, event, events)

    def decommission(self, robot_id: str) -> RobotView:
        """Take a robot out of service: it gets no task, its task under way is requeued (and
        the robot told to stop it), and once lost it no longer counts as an obstacle for
        planning and goal validation. Raises :class:`RobotNotFound`."""
        events: list[FleetEvent] = []
        with self._lock:
            if not self._roster.known(robot_id):
                raise RobotNotFound(f"robot {robot_id} not found")
            self._decommissioned.add(robot_id)
            task = self._task_of_robot(robot_id)
            if task is not None:
                now = self._clock()
                self._requeue(task, now, f"robot {robot_id} decommissioned; requeued", events)
                self._cancel_sent[robot_id] = now
                self._bus.publish_assignment(CancelAssignment(robot_id=robot_id, task_id=task.id))
        self._emit(events)
        self._wake.set()
        return self.robot(robot_id)

    def commission(self, robot_id: str) -> RobotView:
        """Put a decommissioned robot back in service. Raises :class:`RobotNotFound`."""
        with self._lock:
            if not self._roster.known(robot_id):
                raise RobotNotFound(f"robot {robot_id} not found")
            self._decommissioned.discard(robot_id)
        self._wake.set()
        return self.robot(robot_id)

    def _ignored(self, view: RobotView) -> bool:
        """A lost, decommissioned robot: no obstacle any more (it was taken away)."""
        return view.status is RobotStatus.LOST and view.robot_id in self._decommissioned

    # -- background work -----------------------------------------------------------------

    def tick(self) -> None:
        """One step: timeouts, re-sends of unacknowledged assignments, dispatch."""
        events: list[FleetEvent] = []
        with self._lock:
            now = self._clock()
            # Only tasks under way have deadlines and assignments (queued ones wait cheaply).
            for task in list(self._under_way.values()):
                if self._held(task.robot_id):  # paused or e-stopped: the task waits, no timeout
                    self._deadline[task.id] = now + self.settings.task_timeout_s
                    continue
                deadline = self._deadline.get(task.id)
                if deadline is not None and now >= deadline:
                    reason = f"timeout: not arrived within {self.settings.task_timeout_s:g} s"
                    self._finish(task, TaskStatus.FAILED, reason, now, events, True)
            self._recover_stuck(now, events)
            for task in self._under_way.values():
                if task.robot_id is None:
                    continue
                state = self._roster.state(task.robot_id)
                acked = (
                    state is not None
                    and state.task_id == task.id
                    and state.revision >= task.revision
                )
                if not acked and now - self._last_sent.get(task.id, now) >= RESEND_INTERVAL_S:
                    self._send(task, now)
                    self._counters["assignments_resent"] += 1
        self._emit(events)
        self._dispatch()

    def _recover_stuck(self, now: float, events: list[FleetEvent]) -> None:
        """Tasks driving with no progress for ``stuck_after_s``: the next recovery
        (``fleet.service.stuck``), stored with the cause and counted; then failure."""
        for task in list(self._under_way.values()):
            if task.status != TaskStatus.DRIVING or self._held(task.robot_id):
                continue
            if not self._stuck.stuck(task.id, now):
                continue
            assert task.robot_id is not None and task.law is not None
            cause = stuck_cause(
                self._roster.view(task.robot_id),
                self._stuck.silent(task.id, now),
                self._roster.views(),
                self._obstacles,
                self.settings.avoidance.peer_radius,
                self.settings.stuck_after_s,
            )
            self._counters["stuck"] += 1
            step = self._stuck.next_recovery(task.id, now)
            if step is None:
                reason = f"stuck: {cause}; {len(RECOVERIES)} recoveries did not help"
                self._finish(task, TaskStatus.FAILED, reason, now, events, True)
                continue
            self._counters["recoveries"] += 1
            reason = f"stuck: {cause}; recovery {self._stuck.attempts(task.id)}: {step}"
            if step == "requeue":  # to another robot (dispatch avoids this one)
                self._avoid[task.id] = task.robot_id
                self._requeue(task, now, reason, events, "recovery")
                self._cancel_sent[task.robot_id] = now
                self._bus.publish_assignment(
                    CancelAssignment(robot_id=task.robot_id, task_id=task.id)
                )
                continue
            law = task.law
            if step == "flip" and task.request.direction == "auto":
                law = "cw" if task.law == "ccw" else "ccw"
            revised = self._update(task, now, law=law, revision=task.revision + 1, reason=reason)
            self._transition(revised, "recovery", events)
            delay = 0.0 if law != task.law else self.settings.stuck_after_s / 3  # wait
            self._send(revised, now, start_delay_s=delay)

    def _send(self, task: Task, now: float, start_delay_s: float = 0.0) -> None:
        assert task.robot_id is not None and task.law is not None
        request = task.request
        self._last_sent[task.id] = now
        self._bus.publish_assignment(
            ParkAssignment(
                robot_id=task.robot_id,
                task_id=task.id,
                revision=task.revision,
                goal=request.goal,
                law=task.law,
                gains=request.gains_for(task.law),
                tolerance=request.tolerance,
                avoidance=self.settings.avoidance,
                start_delay_s=start_delay_s,
            )
        )

    def _held(self, robot_id: str | None) -> bool:
        """Whether an operator holds the robot still (asked, or it reports so)."""
        if robot_id is None:
            return False
        state = self._roster.state(robot_id)
        return self.control_desk.held(robot_id, None if state is None else state.mode)

    def _free_robots(self) -> list[RobotView]:
        busy = self._robot_task
        return [
            v
            for v in self._roster.views()
            if v.status != RobotStatus.LOST
            and v.robot_id not in busy
            and not self._held(v.robot_id)
            and v.robot_id not in self._decommissioned
        ]

    def _dispatch(self) -> None:
        """Assign queued tasks to free robots and choose their laws (see module docstring)."""
        with self._dispatch_lock:
            with self._lock:
                if self._closed:
                    return
                if not self._queued:
                    return
                free = self._free_robots()
                if not free:
                    return
                # Oldest first (a requeued task keeps its place), as named tasks are served
                # first come, first served; O(queued) only when some robot is free.
                queued = sorted(self._queued.values(), key=lambda t: t.created_at)
                views = {v.robot_id: v for v in self._roster.views()}
                movers = [t for t in self._under_way.values() if t.robot_id in views]
                obstacles = list(self._obstacles)
                lead_time = self._lead_time()
            began, cpu = time.monotonic(), time.thread_time()
            plan, flips = self._plan(queued, free, movers, views, obstacles, lead_time)
            took, cpu = time.monotonic() - began, time.thread_time() - cpu
            _log.info("planned %d task(s): %.2f s wall, %.2f s CPU", len(plan), took, cpu)
            events: list[FleetEvent] = []
            with self._lock:
                self._counters["plans"] += 1
                self._counters["plan_cpu_ms"] += round(1e3 * cpu)
                self._counters["plan_wall_ms"] += round(1e3 * took)
                last = self._plan_seconds
                self._plan_seconds = took if last is None else 0.5 * (last + took)
                now = self._clock()
                for task, law in flips:
                    self._replan(task, law, now, events)
                free_now = {v.robot_id for v in self._free_robots()}
                for task, robot_id, law in plan:
                    current = self._active.get(task.id)
                    if current is None or current.status != TaskStatus.QUEUED:
                        continue
                    if robot_id not in free_now:
                        continue
                    free_now.discard(robot_id)
                    assigned = self._update(
                        current,
                        now,
                        status=TaskStatus.ASSIGNED,
                        robot_id=robot_id,
                        law=law,
                        attempts=current.attempts + 1,
                    )
                    self._transition(assigned, "assigned", events)
                    self._stuck.start(task.id, now)
                    self._deadline[task.id] = now + self.settings.task_timeout_s
                    self._paths[task.id] = deque(maxlen=PATH_SAMPLES)
                    while len(self._paths) > PATHS_KEPT:
                        self._paths.popitem(last=False)
                    self._send(assigned, now)
            self._emit(events)

    def _replan(self, planned: Task, law: Law, now: float, events: list[FleetEvent]) -> None:
        """Give a task under way a new law as ``revision + 1`` (stored, then sent), unless
        it changed since the snapshot the plan was made on."""
        current = self._active.get(planned.id)
        if (
            current is None
            or current.status not in _ACTIVE
            or current.robot_id != planned.robot_id
            or current.law != planned.law
            or current.revision != planned.revision
        ):
            return
        revised = self._update(current, now, law=law, revision=current.revision + 1)
        self._transition(revised, "replanned", events)
        self._counters["replans"] += 1
        self._send(revised, now)

    def _plan(
        self,
        queued: list[Task],
        free: list[RobotView],
        movers: list[Task],
        views: dict[str, RobotView],
        obstacles: list[Obstacle],
        lead_time: float = 0.0,
    ) -> tuple[list[tuple[Task, str, Law]], list[tuple[Task, Law]]]:
        """Pure planning on a snapshot: who takes which task, and with which law; and
        which tasks under way should switch law (strictly safer, see the module docstring)."""
        pairs: list[tuple[Task, RobotView]] = []
        available = {v.robot_id: v for v in free}
        for task in queued:  # named tasks first come, first served
            rid = task.request.robot_id
            if rid is not None and rid in available:
                pairs.append((task, available.pop(rid)))
        unnamed = [t for t in queued if t.request.robot_id is None][: len(available)]
        if unnamed and available:
            robots = list(available.values())
            specs = [
                TaskSpec(
                    goal=t.request.goal.as_tuple(),
                    laws=LAWS if t.request.direction == "auto" else (t.request.direction,),
                    gains={law: t.request.gains_for(law) for law in LAWS},
                    tolerance=t.request.tolerance,
                )
                for t in unnamed
            ]
            cost = predicted_times(
                [r.pose.as_tuple() for r in robots],
                specs,
                self.settings.profile,
                obstacles,
                self.settings.avoidance,
            )
            for j, t in enumerate(unnamed):  # a stuck task goes to another robot if any
                avoid = self._avoid.get(t.id)
                for i, r in enumerate(robots):
                    if r.robot_id == avoid:
                        cost[i, j] += AVOID_COST_S
            for i, j in optimal_assignment(cost):
                pairs.append((unnamed[j], robots[i]))
        if not pairs:
            return [], []

        scene_movers: list[Mover] = []
        moving_ids: set[str] = set()
        for t in movers:  # under way: an auto task may be flipped (revision) if strictly safer
            assert t.robot_id is not None and t.law is not None
            v = views[t.robot_id]
            scene_movers.append(
                Mover(
                    robot_id=t.robot_id,
                    pose=v.pose.as_tuple(),
                    goal=t.request.goal.as_tuple(),
                    gains={law: t.request.gains_for(law) for law in LAWS},
                    tolerance=t.request.tolerance,
                    law=t.law,
                    auto=t.request.direction == "auto",
                )
            )
            moving_ids.add(t.robot_id)
        first_new = len(scene_movers)
        for task, v in pairs:
            direction = task.request.direction
            scene_movers.append(
                Mover(
                    robot_id=v.robot_id,
                    pose=v.pose.as_tuple(),
                    goal=task.request.goal.as_tuple(),
                    gains={law: task.request.gains_for(law) for law in LAWS},
                    tolerance=task.request.tolerance,
                    law=None if direction == "auto" else direction,
                    auto=direction == "auto",
                )
            )
            moving_ids.add(v.robot_id)
        standing = [
            (v.pose.x, v.pose.y)
            for rid, v in views.items()
            if rid not in moving_ids and not self._ignored(v)
        ]
        scene = Scene(
            movers=scene_movers,
            standing=standing,
            obstacles=obstacles,
            avoidance=self.settings.avoidance,
            profile=self.settings.profile,
            lead_time=lead_time,
        )
        if any(m.auto for m in scene_movers):
            decision = choose_directions(
                scene,
                self.settings.safety_separation_m,
                dt=1.0 / self.settings.control_rate_hz,  # the agents' Euler step
            )
            laws = decision.best.laws
            self._counters["direction_choices"] += 1
        else:
            laws = tuple(m.law or "ccw" for m in scene_movers)
        flips = [
            (t, laws[k]) for k, t in enumerate(movers) if laws[k] != t.law
        ]  # movers come first in scene_movers
        return [(task, v.robot_id, laws[first_new + k]) for k, (task, v) in enumerate(pairs)], flips

    # -- API -----------------------------------------------------------------------------

    def _occupied(self, goal: Pose, exclude_robot: str | None) -> list[Occupied]:
        """Active (and pending) goals within the peer radius of ``goal``, nearest first,
        and parked robots (arrived, holding or lost, with no active task)."""
        out = list(self._goals.near(goal.x, goal.y, self.settings.avoidance.peer_radius))
        busy = self._claims
        for v in self._roster.views():
            if v.robot_id == exclude_robot or v.robot_id in busy or self._ignored(v):
                continue
            if v.status in _STANDING:
                out.append(Occupied(v.pose.x, v.pose.y, f"{v.status.value} robot {v.robot_id}"))
        return out

    def submit(self, request: TaskRequest, idempotency_key: str | None = None) -> Task:
        """Validate, store (``queued``) and schedule a parking task; returns the stored task.

        Raises :class:`GoalRejected` (with the reason) or :class:`RobotNotFound`. A repeated
        ``idempotency_key`` returns the task first created with it, whatever the body.
        """
        while True:
            if idempotency_key is not None:
                existing = self._store.find_by_idempotency_key(idempotency_key)
                if existing is not None:
                    return existing
            with self._lock:
                # A request with the same key is being stored: wait for it (its task is
                # the answer), instead of rejecting this one as too near its goal.
                writing = self._keys_in_flight.get(idempotency_key or "")
            if writing is None:
                break
            writing.wait(10.0)
        now = self._clock()
        task = Task(id=uuid.uuid4().hex, request=request, created_at=now, updated_at=now)
        if not self._reserve(task, idempotency_key):
            return self.submit(request, idempotency_key)  # lost a race: wait as above
        try:
            stored = self._store.save_new(task, idempotency_key)
        except BaseException:
            with self._lock:
                self._goals.remove(task.id)
                self._bays.release(task)
            raise
        finally:
            if idempotency_key is not None:
                with self._lock:
                    self._keys_in_flight.pop(idempotency_key).set()
        events: list[FleetEvent] = []
        with self._lock:
            if stored.id != task.id:  # a concurrent request with the same key won
                self._goals.remove(task.id)
                self._bays.release(task)
                return stored
            self._put(stored)  # stored: now the tick thread may dispatch it
            events.append(TaskEvent(task=stored))
        self._emit(events)
        self._last_submit = time.monotonic()
        self._wake.set()
        return stored

    def _reserve(self, task: Task, idempotency_key: str | None) -> bool:
        """Validate ``task``'s goal and reserve it (and its key) for the write; False if a
        request with the same key is being written meanwhile."""
        request, goal = task.request, task.request.goal
        with self._lock:
            if idempotency_key is not None and idempotency_key in self._keys_in_flight:
                return False
            rid = request.robot_id
            if rid is not None and not self._roster.known(rid):
                raise RobotNotFound(f"robot {rid} not found")
            if rid is not None and rid in self._decommissioned:
                raise TaskConflict(f"robot {rid} is decommissioned: commission it first")
            self._bays.check(task)
            validate_goal(
                goal,
                self.settings.yard,
                self._obstacles,
                self._occupied(goal, rid),
                self.settings.avoidance.peer_radius,
                () if self.settings.site is None else self.settings.site.keep_out,
                margin=self.settings.profile.radius,
            )
            # Reserve the goal while the task is written (outside the lock, so concurrent
            # submits share one commit): a concurrent submit near it is rejected meanwhile.
            self._goals.add(task.id, Occupied(goal.x, goal.y, f"the goal of task {task.id}"))
            self._bays.hold(task)
            if idempotency_key is not None:
                self._keys_in_flight[idempotency_key] = threading.Event()
        return True

    def submit_to_bay(
        self,
        bay: str | None,
        group: str | None,
        make: Callable[[Pose, str], TaskRequest],
        idempotency_key: str | None = None,
    ) -> Task:
        """Submit a task whose goal is a named bay, or any free bay of ``group``
        (``make(pose, bay)`` builds the request). The bay is reserved by the task while it
        is active. Raises :class:`BayNotFound` (404) or :class:`BayTaken` / GoalRejected
        (409, e.g. a robot parked there)."""
        with self._lock:
            candidates = self._bays.candidates(bay, group)
        refused: list[str] = []
        for choice in candidates:
            try:
                return self.submit(make(choice.pose, choice.name), idempotency_key)
            except (BayTaken, GoalRejected) as exc:
                if bay is not None:
                    raise
                refused.append(f"{choice.name}: {exc}")
        raise BayTaken(f"no free bay in group {group}: " + "; ".join(refused))

    def bays(self) -> list[BayState]:
        """Every bay of the site map with its state (free, reserved, occupied)."""
        with self._lock:
            return self._bays.states(dict(self._active), self._roster.views())

    def control(
        self, action: ControlAction, robot_id: str | None = None, reason: str | None = None
    ) -> ControlCommand:
        """Pause, resume, e-stop or release one robot or (``None``) the whole fleet: the
        command goes to the robots at once; paused and e-stopped robots keep their tasks
        (no timeout) and take no new ones. Raises :class:`RobotNotFound`."""
        if robot_id is not None:
            with self._lock:
                if not self._roster.known(robot_id):
                    raise RobotNotFound(f"robot {robot_id} not found")
        message = self.control_desk.command(action, robot_id, reason)
        self._wake.set()
        return message

    def cancel(self, task_id: str) -> Task:
        """Cancel a task; :class:`TaskNotFound`, or :class:`TaskConflict` if already final."""
        events: list[FleetEvent] = []
        with self._lock:
            task = self._active.get(task_id)
            if task is None:
                stored = self._store.get(task_id)
                if stored is None:
                    raise TaskNotFound(f"task {task_id} not found")
                raise TaskConflict(f"task {task_id} is already {stored.status.value}")
            done = self._finish(
                task, TaskStatus.CANCELLED, "cancelled by request", self._clock(), events, True
            )
        self._emit(events)
        self._wake.set()
        return done

    def task(self, task_id: str) -> Task:
        with self._lock:
            active = self._active.get(task_id)
        if active is not None:
            return active
        stored = self._store.get(task_id)
        if stored is None:
            raise TaskNotFound(f"task {task_id} not found")
        return stored

    def history(self, task_id: str) -> list[tuple[float, str, Task]]:
        """Every stored transition of a task, oldest first: (time [s since epoch], event
        such as ``assigned`` or ``replanned``, the task as stored then)."""
        rows = self._store.history(task_id)
        if not rows and self._store.get(task_id) is None:
            raise TaskNotFound(f"task {task_id} not found")
        return rows

    def tasks(self, status: TaskStatus | None = None, robot_id: str | None = None) -> list[Task]:
        """Tasks in creation order, optionally filtered (read from the store)."""
        return self._store.list(status=status, robot_id=robot_id)

    def _in_service(self, view: RobotView) -> RobotView:
        if view.robot_id in self._decommissioned:
            return view.model_copy(update={"in_service": False})
        return view

    def robots(self) -> list[RobotView]:
        with self._lock:
            return [self._in_service(v) for v in self._roster.views()]

    def robot(self, robot_id: str) -> RobotView:
        with self._lock:
            view = self._roster.view(robot_id)
            if view is not None:
                view = self._in_service(view)
        if view is None:
            raise RobotNotFound(f"robot {robot_id} not found")
        return view

    def obstacles(self) -> list[Obstacle]:
        with self._lock:
            return list(self._obstacles)

    def set_obstacles(self, obstacles: list[Obstacle]) -> None:
        """Replace the static obstacles and publish them (``ObstacleSet``)."""
        msg = ObstacleSet(obstacles=list(obstacles))
        with self._lock:
            self._obstacles = list(msg.obstacles)
            self._bus.publish_obstacles(msg)

    def path(self, task_id: str) -> list[PathSample]:
        """Recorded (t [s], x [m], y [m], theta [rad], u [m/s], omega [rad/s]) of the task's
        robot while it ran the task (the last ``PATH_SAMPLES``; empty once evicted)."""
        with self._lock:
            path = self._paths.get(task_id)
            if path is not None:
                return list(path)
            known = task_id in self._active
        if not known and self._store.get(task_id) is None:
            raise TaskNotFound(f"task {task_id} not found")
        return []

    @property
    def counters(self) -> dict[str, int]:
        with self._lock:
            out = dict(self._counters)
        desk = self.control_desk
        out["estops_requested"] = desk.requested[ControlAction.ESTOP]
        out["control_requests"] = sum(desk.requested.values())
        out["control_resent"] = desk.resent
        for key, value in self._bus.counters.items():
            out[f"bus_{key}"] = value
        return out
