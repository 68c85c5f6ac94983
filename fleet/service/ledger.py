"""The task ledger: the active tasks, their indexes, and transitions that return effects.

Pure: no threads, no clock, no I/O. The shell (:class:`fleet.service.FleetService`) calls it
under its lock with the time as arguments -- ``now`` [s, monotonic] for deadlines and
re-sends, ``wall`` [s since epoch] for the stored ``updated_at`` -- and applies the returned
:mod:`~fleet.service.effects` after releasing the lock, stored before announced.

Task life cycle::

    queued -> assigned (assignment published) -> driving (robot's state acknowledges it)
           -> succeeded (robot reports ``arrived`` with the task id)
            | failed (timeout ``task_timeout_s`` after assignment; robot lost with
                      ``on_robot_lost == "fail"``; its named robot removed)
            | cancelled
    queued -> waiting (assigned with ``hold``: no safe option yet, ``reason`` says why)
    assigned/driving <-> waiting (a revision holds it / resumes it: assigned until acknowledged)
    assigned/driving/waiting -> queued again when the robot is lost and ``on_robot_lost ==
    "requeue"``, when it is decommissioned, or as the third recovery of a stuck robot
                                (planned for another robot: :meth:`TaskLedger.avoided`)
    driving -> waiting (revision + 1, held) as a recovery of a stuck robot (flip the law,
               or wait), until a plan resumes it

Operator holds (:meth:`TaskLedger.hold_robot`): while an operator holds a robot still
(paused or e-stopped, as asked or as it reports), its task is held (a revision with
``hold``, ``waiting``), its timeout does not run (the deadline moves on by the time held),
it is not stuck, and the planner sees it standing; the hold and its end are stored in the
task's history (``operator_hold`` / ``operator_release``, with the reason). When the
operator lets go, the robot stands until a plan resumes it, so a robot is started or moved
only by a decision that passed the plan's check (:meth:`TaskLedger.apply`).

Stuck robots (:mod:`~fleet.service.stuck`): every state of a robot driving its task feeds
its progress watch; :meth:`TaskLedger.stuck` lists the tasks with no progress for
``stuck_after_s`` and :meth:`TaskLedger.recover_stuck` applies the next recovery (flip, wait,
requeue to another robot) or fails the task, with the cause in its reason and history.
:meth:`TaskLedger.standoffs` lists, sooner, robots ``avoiding`` without progress for
``standoff_after_s`` of their own time; :meth:`TaskLedger.break_standoff` makes one of them
give way (a held revision, the other law pinned), for a plan to resume.

Bays (:mod:`~fleet.service.bays`): a task's bay is held from its reservation until it is
final (or the reservation is given back).

Single-robot zones (:mod:`~fleet.service.zones`): a decision that starts or moves a robot
carries the zones its way enters; it is applied only if no other robot holds one of them
(else :attr:`Outcome.STALE`), and the robot then holds them. Every state of a robot gives
back the zones it has left (:meth:`TaskLedger.observe`: ``zones_changed`` asks for a plan,
so the next robot goes); a robot removed from the fleet gives back every one.

The plan's decisions (:class:`fleet.core.planner.TaskDecision`) are applied by
:meth:`TaskLedger.apply`: ``assign`` gives a queued task its robot, law, start delay or hold;
``revise`` stores ``revision + 1`` with the new law, delay or hold (a flip, a hold, a
resume); ``keep`` sends nothing. A decision made on a task that has since changed (another
revision, robot or status family) is :attr:`Outcome.STALE` and dropped; a decision that would
start, resume or re-plan a moving robot (a new law or start delay) in a plan predicted
unsafe is :attr:`Outcome.UNSAFE` and dropped (holding is always allowed); a decision that
would start a robot an operator holds still changes nothing (``unchanged``): a plan after
the release starts it.

Indexes kept on every transition, so no hot path walks every task: queued tasks, tasks
under way (with a robot), the task of each robot, claims (active tasks naming or holding a
robot), the goal grid (active and reserved goals), per task under way its deadline, last
send, the revision its robot last reported and its predicted corridor; recorded paths
(:class:`~fleet.service.paths.PathRecorder`); and a bounded memory of recently finished
task ids (a robot still driving one is told to stop without a store read).

:attr:`TaskLedger.version` rises with every change a plan depends on: a task put in or
dropped from the active set (every transition, a new or recovered task), a robot held or
released by an operator. The service compares it (with the roster's) to tell a stale plan.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter, OrderedDict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Literal

from fleet.core.goals import GoalIndex, Occupied
from fleet.core.params import Avoidance
from fleet.core.planner.model import TaskDecision
from fleet.core.site import Site
from fleet.core.tasks import Task, TaskEvent, TaskNotFound, TaskStatus
from fleet.core.types import Law
from fleet.core.wire import CancelAssignment, ParkAssignment, RobotMode, RobotState
from fleet.core.zones import Point, declared, way
from fleet.io.settings import Settings
from fleet.service.bays import BayBook
from fleet.service.effects import Effects, Notify, Publish, StoreWrite
from fleet.service.horizon import Corridor
from fleet.service.paths import PathRecorder
from fleet.service.snapshot import LedgerFacts
from fleet.service.stuck import RECOVERIES, StuckWatch
from fleet.service.zones import ZoneBook

#: Robot modes in which a robot drives a task (a stray one is told to stop).
_MOVING = frozenset({RobotMode.DRIVING, RobotMode.AVOIDING})
#: Robot modes of a robot standing still on purpose (not stuck).
_STILL_ON_PURPOSE = frozenset({RobotMode.WAITING, RobotMode.PAUSED, RobotMode.ESTOP})
#: How many finished task ids are remembered for stray robots.
FINISHED_REMEMBERED = 10_000
#: The reason of a task whose robot an operator let go, until a plan resumes it.
RELEASED_REASON = "released by the operator: waiting for the next plan"
#: [s] between re-sends of an unacknowledged assignment (and, by the service, of a cancel).
RESEND_INTERVAL_S = 0.2
_NEVER = float("-inf")


class Outcome(StrEnum):
    """What became of one decision of a plan."""

    APPLIED = "applied"  # stored, then sent
    UNCHANGED = "unchanged"  # same as what the robot has (or operator-held): nothing sent
    STALE = "stale"  # the task changed since the snapshot: dropped
    UNSAFE = "unsafe"  # would move a robot in a plan predicted unsafe: dropped


@dataclass(frozen=True)
class LedgerConfig:
    """The settings the ledger's transitions depend on."""

    task_timeout_s: float = 120.0  # [s] from assignment
    resend_interval_s: float = RESEND_INTERVAL_S
    on_robot_lost: Literal["fail", "requeue"] = "fail"
    avoidance: Avoidance = field(default_factory=Avoidance)  # sent with every assignment
    goal_cell: float = 1.0  # [m] cell of the goal grid (the peer radius)
    corridor_m: float = 0.3  # [m] an observed pose farther than this from its prediction
    control_hz: float = 50.0  # the robots' control rate (state seq per second)
    stuck_after_s: float = 30.0  # [s] no progress this long: stuck (recoveries, then failed)
    #: [s, robot time] avoiding with no progress this long: a standoff (one robot gives way)
    standoff_after_s: float = math.inf
    #: [m] progress that restarts the standoff window (less in it: no way out)
    standoff_progress_m: float = 0.05
    #: [m] a law a recovery or a standoff pinned holds until its robot has come this much
    #: nearer its goal than it was then (:meth:`TaskLedger.pinned`)
    pin_release_m: float = 0.5


def ledger_config(settings: Settings) -> LedgerConfig:
    """The ledger's settings as the fleet service takes them from its ``settings`` (also the
    offline fleet's, so it predicts the service)."""
    return LedgerConfig(
        task_timeout_s=settings.task_timeout_s,
        on_robot_lost=settings.on_robot_lost,
        avoidance=settings.avoidance,
        goal_cell=max(settings.avoidance.peer_radius, 0.1),
        corridor_m=settings.replan_corridor_m,
        control_hz=settings.control_rate_hz,
        stuck_after_s=settings.stuck_after_s,
        standoff_after_s=settings.standoff_after_s,
        standoff_progress_m=settings.standoff_progress_m,
    )


@dataclass(slots=True)
class _Tracking:
    """Service-side bookkeeping of one task under way."""

    deadline: float  # [s, monotonic]
    sent_at: float  # last send of the current revision [s, monotonic]
    seen_revision: int = -1  # revision its robot last reported for it (-1: not this task)
    acked: tuple[int, float] | None = None  # (revision, first report of it [s, monotonic])
    corridor: Corridor | None = None
    held_at: float | None = None  # an operator holds its robot since [s, monotonic]
    reason_before_hold: str | None = None  # the task's reason when the hold began


@dataclass(frozen=True, slots=True)
class Observation:
    """What one robot state did to the ledger."""

    effects: Effects
    finished: bool = False  # the robot's task ended (arrived)
    stray: bool = False  # the robot drives a task that is not active (maybe finished)
    off_corridor: bool = False  # the robot left its predicted corridor
    zones_changed: bool = False  # it took or gave back a single-robot zone


_NOTHING = Observation([])
_STRAY = Observation([], stray=True)


def _suffix(rest: Sequence[tuple[float, float]], route: Sequence[tuple[float, float]]) -> bool:
    """Whether the via-points ``rest`` end ``route`` (what is left of it: no new route; an
    empty ``rest`` of a route is a new, straight way unless the decision says the robot is
    on its last leg, ``TaskDecision.last_leg``)."""
    if not rest:
        return not route
    tail = [tuple(p) for p in route[len(route) - len(rest) :]]
    return len(rest) <= len(route) and tail == [tuple(p) for p in rest]


def assignment_of(task: Task, avoidance: Avoidance) -> ParkAssignment:
    """The message that gives ``task`` (under way) to its robot, as last decided."""
    assert task.robot_id is not None and task.law is not None
    request = task.request
    return ParkAssignment(
        robot_id=task.robot_id,
        task_id=task.id,
        revision=task.revision,
        goal=request.goal,
        law=task.law,
        gains=request.gains_for(task.law),
        tolerance=request.tolerance,
        avoidance=avoidance,
        start_delay_s=task.start_delay_s,
        hold=task.hold,
        route=task.route,
        pass_m=task.pass_m,
    )


class TaskLedger:
    """Active tasks and their transitions (see the module docstring)."""

    def __init__(
        self, config: LedgerConfig, paths: PathRecorder | None = None, site: Site | None = None
    ) -> None:
        self.config = config
        self.paths = paths if paths is not None else PathRecorder()
        self.bays = BayBook(site)  # bay -> the active (or reserved) task holding it
        self.zones = ZoneBook(declared(site))  # single-robot zone -> the robot holding it
        # progress of tasks under way (stuck robots, standoffs)
        self.stuck_watch = StuckWatch(
            config.stuck_after_s,
            standoff_after_s=config.standoff_after_s,
            standoff_progress_m=config.standoff_progress_m,
        )
        self._held: dict[str, str] = {}  # robots an operator holds still -> why
        self._avoid: dict[str, str] = {}  # task -> robot it was taken from (stuck)
        #: task under way -> the law a recovery chose, and its robot's remaining distance
        #: to the goal then [m] (:meth:`StuckWatch.left`; inf: unknown)
        self._pinned: dict[str, tuple[Law, float]] = {}
        self._own_way: set[str] = set()  # tasks under way a recovery took off their route
        self._wide_way: set[str] = set()  # tasks under way a recovery sent round posts' zones
        self._gave_way: set[str] = set()  # tasks whose robot gave way in a standoff, held
        self._zone_wait: dict[str, str] = {}  # tasks the plan holds for a zone -> the zone
        self._round: dict[str, tuple[str, ...]] = {}  # task -> standing robots it goes round
        self._active: dict[str, Task] = {}  # every non-final task, by id
        self._queued: dict[str, Task] = {}
        self._under_way: dict[str, Task] = {}  # assigned, driving, waiting (with a robot)
        self._robot_task: dict[str, str] = {}  # robot -> its task under way
        self._claims: Counter[str] = Counter()  # robot -> active tasks naming or holding it
        self._goals = GoalIndex(max(config.goal_cell, 0.1))  # active + reserved goals
        self._tracking: dict[str, _Tracking] = {}  # task under way -> bookkeeping
        self._finished: OrderedDict[str, TaskStatus] = OrderedDict()
        self._version = 0  # see the module docstring

    @property
    def version(self) -> int:
        """Rises with every change a plan depends on (tasks, operator holds)."""
        return self._version

    # -- reading -----------------------------------------------------------------------

    @property
    def active(self) -> Mapping[str, Task]:
        return self._active

    @property
    def queued(self) -> Mapping[str, Task]:
        return self._queued

    @property
    def under_way(self) -> Mapping[str, Task]:
        return self._under_way

    @property
    def robot_task(self) -> Mapping[str, str]:
        return self._robot_task

    @property
    def claims(self) -> Mapping[str, int]:
        return self._claims

    @property
    def goals(self) -> GoalIndex:
        return self._goals

    def get(self, task_id: str) -> Task | None:
        return self._active.get(task_id)

    def task_of_robot(self, robot_id: str) -> Task | None:
        task_id = self._robot_task.get(robot_id)
        return None if task_id is None else self._under_way.get(task_id)

    def finished_status(self, task_id: str) -> TaskStatus | None:
        """The final status of a recently finished task (None: unknown or still active)."""
        return self._finished.get(task_id)

    @property
    def held(self) -> Mapping[str, str]:
        """Robots an operator holds still, with why."""
        return self._held

    def avoided(self) -> dict[str, str]:
        """Queued tasks taken from a stuck robot -> that robot (the planner gives them to
        another robot if it can)."""
        return {tid: rid for tid, rid in self._avoid.items() if tid in self._queued}

    def pinned(self) -> dict[str, Law]:
        """Tasks under way whose law a stuck recovery or a standoff flipped -> that law
        (the planner keeps it: the robot was held with the other), until the robot has come
        ``pin_release_m`` nearer its goal than it was then: it has left that place, and the
        plans choose its law again (near its goal, the one that arrives sooner). A pin once
        released is gone: a robot that then backs away is not pinned again."""
        release = self.config.pin_release_m
        for task_id in [
            task_id
            for task_id, (_, at) in self._pinned.items()
            if math.isfinite(at) and self.stuck_watch.left(task_id) <= at - release
        ]:
            del self._pinned[task_id]
        return {task_id: law for task_id, (law, _) in self._pinned.items()}

    def own_way(self) -> frozenset[str]:
        """Tasks under way a stuck recovery took off their route (the planner routes them
        no more: their robot stalled on it)."""
        return frozenset(self._own_way)

    def wide_way(self) -> frozenset[str]:
        """Tasks under way a stuck recovery, finding them without a route, sent round the
        posts' Eq. (27) zones (the planner routes them so: their robot stalled in one)."""
        return frozenset(self._wide_way)

    def gave_way(self) -> frozenset[str]:
        """Tasks whose robot gave way in a standoff and stands until a plan resumes it (the
        planner sends the other robots round it: with both laws driving straight at each
        other, nothing else gets one past the other)."""
        return frozenset(self._gave_way)

    def round_robots(self) -> dict[str, tuple[str, ...]]:
        """Tasks under way -> the standing robots that held their robot off in a standoff
        (the planner routes it round them while they stand: giving way to a robot that does
        not move changes nothing)."""
        return dict(self._round)

    def facts(self, now: float) -> LedgerFacts:
        """What a plan needs from the ledger beside its tasks, copied, at ``now`` [s, the
        clock the ledger observes with] (the service's snapshot and the offline fleet's)."""
        return LedgerFacts(
            held=frozenset(self.held),
            avoided=self.avoided(),
            acknowledged_s={t: now - at for t, at in self.acknowledged_at().items()},
            pinned=self.pinned(),
            own_way=self.own_way(),
            wide_way=self.wide_way(),
            gave_way=self.gave_way(),
            round_robots=self.round_robots(),
            zones=self.zones.shapes,
            zone_holders=self.zones.holders(),
        )

    def acknowledged_at(self) -> dict[str, float]:
        """Tasks under way whose robot reports their current revision -> when it first did
        [s, monotonic] (its start delay counts from about then)."""
        out = {}
        for task_id, track in self._tracking.items():
            task = self._under_way.get(task_id)
            if task is not None and track.acked is not None and track.acked[0] == task.revision:
                out[task_id] = track.acked[1]
        return out

    def sent_revision_acknowledged(self, task_id: str) -> bool:
        track = self._tracking.get(task_id)
        task = self._under_way.get(task_id)
        return track is not None and task is not None and track.seen_revision >= task.revision

    def sizes(self) -> dict[str, int]:
        """Entries of each structure (all bounded by the active tasks, or by a cap)."""
        return {
            "tasks_active": len(self._active),
            "tasks_queued": len(self._queued),
            "tasks_under_way": len(self._under_way),
            "goals_reserved": len(self._goals),
            "tasks_finished_remembered": len(self._finished),
            "paths": len(self.paths),
            "path_samples": self.paths.samples,
            "bays_reserved": len(self.bays),
            "zones_held": len(self.zones),
            "tasks_watched_stuck": len(self.stuck_watch),
            "robots_held": len(self._held),
        }

    # -- indexes -----------------------------------------------------------------------

    def _put(self, task: Task) -> None:
        """Insert or replace a non-final task in the active set and its indexes."""
        self._version += 1
        old = self._active.get(task.id)
        if old is not None:
            self._unindex(old)
        goal = task.request.goal
        self._goals.add(task.id, Occupied(goal.x, goal.y, f"the goal of task {task.id}"))
        self.bays.hold(task)
        self._active[task.id] = task
        if task.status is TaskStatus.QUEUED:
            self._queued[task.id] = task
        elif task.status.under_way and task.robot_id is not None:
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

    def _drop(self, task: Task) -> None:
        """Remove a task that became final from the active set and its indexes."""
        self._version += 1
        old = self._active.pop(task.id, None)
        if old is not None:
            self._unindex(old)
        self._goals.remove(task.id)
        self.bays.release(task.id)
        self.stuck_watch.forget(task.id)
        self._avoid.pop(task.id, None)
        self._forget_ways(task.id)
        self._tracking.pop(task.id, None)
        self.paths.finish(task.id)
        self._finished[task.id] = task.status
        while len(self._finished) > FINISHED_REMEMBERED:
            self._finished.popitem(last=False)

    def _forget_ways(self, task_id: str) -> None:
        """Drop what recoveries and standoffs pinned for the task (its law, its way, that
        its robot gave way)."""
        self._pinned.pop(task_id, None)
        self._own_way.discard(task_id)
        self._wide_way.discard(task_id)
        self._gave_way.discard(task_id)
        self._zone_wait.pop(task_id, None)
        self._round.pop(task_id, None)

    def _transition(self, task: Task, event: str, effects: Effects) -> None:
        """Record ``task``'s new version in memory; store it, then announce it."""
        if task.status.final:
            self._drop(task)
        else:
            self._put(task)
        effects.append(StoreWrite(task, event))
        effects.append(Notify(TaskEvent(task=task)))

    @staticmethod
    def _update(task: Task, wall: float, **changes: object) -> Task:
        return task.model_copy(update={**changes, "updated_at": wall})

    # -- new tasks ---------------------------------------------------------------------

    def reserve(self, task: Task) -> None:
        """Hold ``task``'s goal (and bay) while it is being stored (a goal near it, or a
        task for the same bay, is rejected meanwhile). Check the bay first
        (``bays.check``)."""
        goal = task.request.goal
        self._goals.add(task.id, Occupied(goal.x, goal.y, f"the goal of task {task.id}"))
        self.bays.hold(task)

    def release(self, task_id: str) -> None:
        """Give back a reservation whose task was not stored."""
        if task_id not in self._active:
            self._goals.remove(task_id)
            self.bays.release(task_id)

    def add(self, task: Task) -> Effects:
        """A new task was stored (``queued``): it may be planned from now on."""
        self._put(task)
        return [Notify(TaskEvent(task=task))]

    def recover(self, tasks: Iterable[Task], now: float) -> int:
        """Unfinished tasks read back from the store at start-up. Those under way keep their
        robot and law; their assignment is re-sent until acknowledged, their timeout
        restarts ``now``."""
        n = 0
        for task in tasks:
            self._put(task)
            if task.status.under_way and task.robot_id is not None:
                self._tracking[task.id] = _Tracking(now + self.config.task_timeout_s, _NEVER)
                self.paths.start(task.id)
                self.stuck_watch.start(task.id, now)
            n += 1
        return n

    # -- robot reports -----------------------------------------------------------------

    def observe(self, state: RobotState, now: float, wall: float) -> Observation:
        """A robot's state: single-robot zones it took or left, acknowledgement, arrival,
        path recording, progress (stuck), corridor check."""
        task_id = self._robot_task.get(state.robot_id)
        if self.zones and self.zones.observe(
            state.robot_id, state.pose.x, state.pose.y, self._way_of(task_id, state)
        ):
            self._version += 1
            seen = self._observe_task(task_id, state, now, wall)
            return dataclasses.replace(seen, zones_changed=True)
        return self._observe_task(task_id, state, now, wall)

    def _way_of(self, task_id: str | None, state: RobotState) -> Callable[[], list[Point]] | None:
        """The rest of the way of the robot of ``state`` (None: it has no task under way)."""
        task = None if task_id is None else self._under_way.get(task_id)
        if task is None:
            return None
        goal = task.request.goal
        p = state.pose
        return lambda: way(p.x, p.y, task.route, (goal.x, goal.y))

    def _observe_task(
        self, task_id: str | None, state: RobotState, now: float, wall: float
    ) -> Observation:
        if task_id is None or state.task_id != task_id:
            if task_id is not None:
                self._tracking[task_id].seen_revision = -1  # it does not run its task
            if (
                state.task_id is not None
                and state.mode in _MOVING
                and state.task_id not in self._active
            ):
                return _STRAY
            return _NOTHING
        task = self._under_way[task_id]
        track = self._tracking[task_id]
        track.seen_revision = state.revision
        if state.revision == task.revision and (
            track.acked is None or track.acked[0] != task.revision
        ):
            track.acked = (task.revision, now)  # the robot's start delay began about now
        p = state.pose
        self.paths.record(task_id, (wall, p.x, p.y, p.theta, state.u, state.omega))
        if state.mode is RobotMode.ARRIVED:
            return Observation(self._finish(task, TaskStatus.SUCCEEDED, None, wall, False), True)
        still = state.mode in _STILL_ON_PURPOSE or track.held_at is not None or task.hold
        self.stuck_watch.observe(
            task_id,
            p,
            task.request.goal,
            now,
            still,
            robot_t=state.seq / self.config.control_hz,
            avoiding=state.mode is RobotMode.AVOIDING,
        )
        effects: Effects = []
        if task.status is TaskStatus.ASSIGNED and state.revision >= task.revision:
            driving = self._update(task, wall, status=TaskStatus.DRIVING)
            self._transition(driving, "acknowledged", effects)
        corridor = track.corridor
        if corridor is None or corridor.tripped or state.revision != corridor.revision:
            return Observation(effects) if effects else _NOTHING
        if corridor.origin_seq is None:  # the robot applied the decision: its t = 0
            corridor.origin_seq = float(state.seq)
        deviation = corridor.deviation(state.seq, p.x, p.y)
        off = deviation is not None and deviation > self.config.corridor_m
        if off:
            corridor.tripped = True
        return Observation(effects, off_corridor=off) if effects or off else _NOTHING

    # -- plans -------------------------------------------------------------------------

    def apply(
        self,
        decision: TaskDecision,
        *,
        robot_available: bool,
        plan_safe: bool,
        origin_seq: float | None,
        now: float,
        wall: float,
        relaxed: str | None = None,
    ) -> tuple[Outcome, Effects]:
        """Apply one decision of a plan (see the module docstring).

        ``robot_available``: the decision's robot may take a new task now; ``origin_seq``:
        the robot's state seq at t = 0 of the plan (for the corridor of a kept decision);
        ``relaxed``: the plan's note when it was made at the standstill margin -- a robot it
        starts or re-plans carries it as its task's reason, so the history says so.
        """
        outcome, effects = self._apply(
            decision, robot_available, plan_safe, origin_seq, now, wall, relaxed
        )
        if outcome in (Outcome.APPLIED, Outcome.UNCHANGED):
            if decision.hold and decision.waits_for is not None:
                self._zone_wait[decision.task_id] = decision.waits_for
            else:
                self._zone_wait.pop(decision.task_id, None)
        return outcome, effects

    def _apply(
        self,
        decision: TaskDecision,
        robot_available: bool,
        plan_safe: bool,
        origin_seq: float | None,
        now: float,
        wall: float,
        relaxed: str | None,
    ) -> tuple[Outcome, Effects]:
        task = self._active.get(decision.task_id)
        if task is None:
            return Outcome.STALE, []
        if decision.action == "assign":
            return self._assign(task, decision, robot_available, plan_safe, now, wall, relaxed)
        if not (
            task.status.under_way
            and task.robot_id == decision.robot_id
            and task.revision == decision.revision
        ):
            return Outcome.STALE, []
        track = self._tracking[task.id]
        wanted = (decision.law, decision.start_delay_s, decision.hold)
        # a new way round, not the rest of the route (nothing left of it on the last leg)
        rerouted = not (decision.last_leg or _suffix(decision.route, task.route))
        unchanged = decision.action == "keep" or wanted == (task.law, task.start_delay_s, task.hold)
        moves = not decision.hold
        if moves and not self.zones.can_take(decision.robot_id, decision.zones):
            return Outcome.STALE, []  # another robot holds a zone on its way
        if unchanged and not rerouted:
            if decision.corridor:
                track.corridor = self._corridor(task.revision, decision, origin_seq)
            if moves:
                self._take_zones(decision)
            return Outcome.UNCHANGED, []
        if task.robot_id in self._held and not decision.hold:
            return Outcome.UNCHANGED, []  # an operator holds it: a plan after the release
        resumes = task.hold and not decision.hold
        if not decision.hold and not plan_safe:
            return Outcome.UNSAFE, []  # it would start, resume or re-route a robot
        reason: str | None
        if decision.hold:
            status, reason, event = TaskStatus.WAITING, self._hold_reason(decision), "held"
        elif resumes:
            status, reason, event = TaskStatus.ASSIGNED, relaxed, "resumed"
            self._gave_way.discard(task.id)
        else:
            status, reason, event = task.status, relaxed or task.reason, "replanned"
        revised = self._update(
            task,
            wall,
            status=status,
            reason=reason,
            law=decision.law,
            start_delay_s=decision.start_delay_s,
            hold=decision.hold,
            revision=task.revision + 1,
            route=list(decision.route),
            pass_m=decision.pass_m,
        )
        effects: Effects = []
        self._transition(revised, event, effects)
        track.sent_at = now
        track.corridor = self._corridor(revised.revision, decision, None)
        if moves:
            self._take_zones(decision)
        effects.append(Publish(assignment_of(revised, self.config.avoidance)))
        return Outcome.APPLIED, effects

    def _take_zones(self, decision: TaskDecision) -> None:
        """The decision's robot holds the zones of its way (checked free by the caller)."""
        if self.zones.take(decision.robot_id, decision.zones):
            self._version += 1

    def _assign(
        self,
        task: Task,
        decision: TaskDecision,
        robot_available: bool,
        plan_safe: bool,
        now: float,
        wall: float,
        relaxed: str | None,
    ) -> tuple[Outcome, Effects]:
        named = task.request.robot_id
        if (
            task.status is not TaskStatus.QUEUED
            or task.revision != decision.revision
            or not robot_available
            or decision.robot_id in self._robot_task
            or (named is not None and named != decision.robot_id)
        ):
            return Outcome.STALE, []
        if not decision.hold and not plan_safe:
            return Outcome.UNSAFE, []
        if not decision.hold and not self.zones.can_take(decision.robot_id, decision.zones):
            return Outcome.STALE, []  # another robot holds a zone on its way
        assigned = self._update(
            task,
            wall,
            status=TaskStatus.WAITING if decision.hold else TaskStatus.ASSIGNED,
            reason=self._hold_reason(decision) if decision.hold else relaxed,
            robot_id=decision.robot_id,
            law=decision.law,
            start_delay_s=decision.start_delay_s,
            hold=decision.hold,
            attempts=task.attempts + 1,
            route=list(decision.route),
            pass_m=decision.pass_m,
        )
        effects: Effects = []
        self._transition(assigned, "assigned", effects)
        self._tracking[task.id] = _Tracking(
            deadline=now + self.config.task_timeout_s,
            sent_at=now,
            corridor=self._corridor(assigned.revision, decision, None),
        )
        self.paths.start(task.id)
        self.stuck_watch.start(task.id, now)
        if not decision.hold:
            self._take_zones(decision)
        effects.append(Publish(assignment_of(assigned, self.config.avoidance)))
        return Outcome.APPLIED, effects

    @staticmethod
    def _hold_reason(decision: TaskDecision) -> str:
        return decision.reason or "waiting: no safe option was found yet"

    def _corridor(
        self, revision: int, decision: TaskDecision, origin_seq: float | None
    ) -> Corridor | None:
        if not decision.corridor:
            return None
        return Corridor(revision, decision.corridor, self.config.control_hz, origin_seq)

    # -- endings -----------------------------------------------------------------------

    def _finish(
        self, task: Task, status: TaskStatus, reason: str | None, wall: float, stop_robot: bool
    ) -> Effects:
        done = self._update(task, wall, status=status, reason=reason)
        effects: Effects = []
        self._transition(done, status.value, effects)
        if stop_robot and task.robot_id is not None and task.status.under_way:
            effects.append(Publish(CancelAssignment(robot_id=task.robot_id, task_id=task.id)))
        return effects

    def cancel(self, task_id: str, wall: float) -> tuple[Task, Effects]:
        """Cancel an active task (its robot, if any, is told to stop); returns the cancelled
        task. :class:`TaskNotFound` if it is not active."""
        task = self._active.get(task_id)
        if task is None:
            raise TaskNotFound(f"task {task_id} is not active")
        effects = self._finish(task, TaskStatus.CANCELLED, "cancelled by request", wall, True)
        return self._finished_version(effects), effects

    @staticmethod
    def _finished_version(effects: Effects) -> Task:
        return next(e.task for e in effects if isinstance(e, StoreWrite))

    def robot_lost(self, robot_id: str, now: float, wall: float) -> Effects:
        """The robot's liveliness token disappeared: its task fails or is queued again."""
        task = self.task_of_robot(robot_id)
        if task is None:
            return []
        reason = f"robot {robot_id} lost (liveliness token gone)"
        if self.config.on_robot_lost == "fail":
            return self._finish(task, TaskStatus.FAILED, reason, wall, False)
        return self._requeue(task, reason + "; requeued", "requeued", wall, stop_robot=False)

    def _requeue(
        self, task: Task, reason: str, event: str, wall: float, *, stop_robot: bool
    ) -> Effects:
        """Put a task under way back in the queue (a task naming its robot keeps it);
        ``stop_robot``: tell the robot to stop it. The revision goes up: a robot that still
        holds the cancelled (or lost) version takes the task again if it is given back."""
        requeued = self._update(
            task,
            wall,
            status=TaskStatus.QUEUED,
            robot_id=task.request.robot_id,
            law=None,
            hold=False,
            start_delay_s=0.0,
            route=[],
            reason=reason,
            revision=task.revision + 1,
        )
        self._tracking.pop(task.id, None)
        self._forget_ways(task.id)  # another robot may take it: its own best law and way
        effects: Effects = []
        self._transition(requeued, event, effects)
        if stop_robot and task.robot_id is not None:
            effects.append(Publish(CancelAssignment(robot_id=task.robot_id, task_id=task.id)))
        return effects

    def robot_decommissioned(self, robot_id: str, wall: float) -> Effects:
        """An operator took the robot out of service: its task under way is queued again
        (for another robot) and the robot told to stop it."""
        task = self.task_of_robot(robot_id)
        if task is None:
            return []
        reason = f"robot {robot_id} decommissioned; requeued"
        return self._requeue(task, reason, "requeued", wall, stop_robot=True)

    # -- operator holds ----------------------------------------------------------------

    def hold_robot(self, robot_id: str, why: str, now: float, wall: float) -> Effects:
        """An operator holds the robot still (paused or e-stopped): its task's timeout stops
        and it is not stuck; stored in the task's history (``operator_hold``). A task under
        way and not held already gets a held revision (``hold``, sent; the agent applies
        assignments while paused), so when the operator lets go the robot stands until a
        plan resumes it through the plan's safety check (:meth:`apply`)."""
        if robot_id in self._held:
            return []
        self._held[robot_id] = why
        self._version += 1
        task = self.task_of_robot(robot_id)
        if task is None:
            return []
        track = self._tracking[task.id]
        track.held_at, track.reason_before_hold = now, task.reason
        effects: Effects = []
        if task.hold:
            self._transition(self._update(task, wall, reason=why), "operator_hold", effects)
            return effects
        held = self._update(
            task,
            wall,
            status=TaskStatus.WAITING,
            reason=why,
            hold=True,
            revision=task.revision + 1,
        )
        self._transition(held, "operator_hold", effects)
        track.sent_at, track.corridor = now, None
        effects.append(Publish(assignment_of(held, self.config.avoidance)))
        return effects

    def release_robot(self, robot_id: str, now: float, wall: float) -> Effects:
        """The operator's hold on the robot ended: its task's deadline moves on by the time
        held, its progress window restarts; stored (``operator_release``). The task stays
        held (:meth:`hold_robot`) until a plan resumes it."""
        if self._held.pop(robot_id, None) is None:
            return []
        self._version += 1
        task = self.task_of_robot(robot_id)
        if task is None:
            return []
        track = self._tracking[task.id]
        if track.held_at is not None:
            track.deadline += now - track.held_at
        reason, track.held_at, track.reason_before_hold = track.reason_before_hold, None, None
        if task.hold:
            reason = RELEASED_REASON if reason is None else f"{reason} ({RELEASED_REASON})"
        self.stuck_watch.start(task.id, now)
        effects: Effects = []
        self._transition(self._update(task, wall, reason=reason), "operator_release", effects)
        return effects

    # -- stuck robots ------------------------------------------------------------------

    def stuck(self, now: float) -> list[Task]:
        """Tasks driving, their robot not held, with no progress for ``stuck_after_s``."""
        watch = self.stuck_watch
        return [
            t
            for t in self._under_way.values()
            if t.status is TaskStatus.DRIVING
            and self._tracking[t.id].held_at is None
            and watch.stuck(t.id, now)
        ]

    def standoffs(self, after_s: float | None = None) -> list[Task]:
        """Tasks driving, their robot not held, in a standoff (:mod:`~fleet.service.stuck`)
        of ``after_s`` robot seconds (default: the standoff window)."""
        watch = self.stuck_watch
        return [
            t
            for t in self._under_way.values()
            if t.status is TaskStatus.DRIVING
            and self._tracking[t.id].held_at is None
            and not t.hold
            and watch.standoff(t.id, after_s)
        ]

    def stands_aside(self, task: Task, robot_id: str) -> bool:
        """Robot ``robot_id``, in a standoff, is held off by ``task``'s robot, which the
        plan holds until a zone ``robot_id`` holds is free -- each waits for the other --:
        the planner sends the others round it as round one that gave way (:meth:`gave_way`).
        False -- it waits for nothing ``robot_id`` holds, or already stands aside -- and the
        standoff is broken the usual way."""
        zone = self._zone_wait.get(task.id)
        if (
            task.id not in self._under_way
            or not task.hold
            or zone is None
            or zone not in self.zones.held_by(robot_id)
            or task.id in self._gave_way
        ):
            return False
        self._gave_way.add(task.id)
        self._version += 1  # the plans route the others round it now
        return True

    def goes_round(self, task_id: str, robot_id: str) -> bool:
        """The task's robot, in a standoff, is held off by ``robot_id``, which stands (no
        task under way): the planner routes it round that robot (:meth:`round_robots`) and
        its stuck window restarts. False -- it went round that robot before -- and the
        standoff is broken the usual way."""
        if task_id not in self._under_way or robot_id in self._round.get(task_id, ()):
            return False
        self._round[task_id] = (*self._round.get(task_id, ()), robot_id)
        self.stuck_watch.restart(task_id)
        self._version += 1
        return True

    def break_standoff(self, task_id: str, cause: str, now: float, wall: float) -> Effects:
        """The task's robot gives way in a standoff: a held revision (it stands until a plan
        resumes it through the plan's check), with the other law pinned for an ``auto``
        task -- another sense of rotation is another way past -- and the others routed round
        it while it stands (:meth:`gave_way`). ``cause`` goes into the reason and the
        history (``standoff``); the task's stuck window is not spent."""
        task = self._under_way[task_id]
        law = self._other_law(task)
        reason = f"standoff: {cause}; gives way ({law}) until a plan resumes it"
        self.stuck_watch.restart(task_id)
        self._gave_way.add(task_id)
        return self._held_revision(task, law, reason, "standoff", now, wall)

    def _other_law(self, task: Task) -> Law:
        """The other law for an ``auto`` task, pinned for the planner; else its own."""
        assert task.law is not None
        if task.request.direction != "auto":
            return task.law
        law: Law = "cw" if task.law == "ccw" else "ccw"
        self._pinned[task.id] = (law, self.stuck_watch.left(task.id))
        return law

    def _held_revision(
        self, task: Task, law: Law, reason: str, event: str, now: float, wall: float
    ) -> Effects:
        """A held revision of ``task`` with ``law`` (it stands until a plan resumes it)."""
        revised = self._update(
            task,
            wall,
            status=TaskStatus.WAITING,
            law=law,
            start_delay_s=0.0,
            hold=True,
            revision=task.revision + 1,
            reason=reason,
        )
        effects: Effects = []
        self._transition(revised, event, effects)
        track = self._tracking[task.id]
        track.sent_at, track.corridor = now, None
        effects.append(Publish(assignment_of(revised, self.config.avoidance)))
        return effects

    def silent(self, task_id: str, now: float) -> bool:
        """No state of the task's robot for the whole stuck window."""
        return self.stuck_watch.silent(task_id, now)

    def recover_stuck(
        self,
        task_id: str,
        cause: str,
        now: float,
        wall: float,
        by_post: bool = False,
        alone: bool = False,
    ) -> Effects:
        """The next recovery of a stuck task (:data:`~fleet.service.stuck.RECOVERIES`):
        ``flip`` -- another way past: a held revision with the other law (``auto`` tasks),
        the law pinned for the planner (:meth:`pinned`), and -- within a post's influence
        radius (``by_post``), without a route or ``alone`` (no robot within the peer
        radius) -- routed round the posts' Eq. (27) zones (:meth:`wide_way`: two posts'
        terms can hold a robot in a gap's mouth for good, on a route through the gap as
        well as without one; the law's own way from the mouth may circle there), else off
        its route when it has one (:meth:`own_way`: the law's own way; a robot stalls on a
        route where Eq. (27) holds it off a via-point; robots near each other sent round the
        posts meet again there); ``wait`` -- a held revision, so a peer passes; either way
        the robot stands until a plan resumes it through the plan's check (:meth:`apply`),
        with the start delay the plan chooses. ``requeue`` -- queued again, its robot told
        to stop, planned for another robot if there is one; after the last the task fails.
        ``cause`` (what the service sees) goes into the reason and the history
        (``recovery``)."""
        task = self._under_way[task_id]
        assert task.robot_id is not None and task.law is not None
        step = self.stuck_watch.next_recovery(task_id, now)
        if step is None:
            reason = f"stuck: {cause}; {len(RECOVERIES)} recoveries did not help"
            return self._finish(task, TaskStatus.FAILED, reason, wall, True)
        reason = f"stuck: {cause}; recovery {self.stuck_watch.attempts(task_id)}: {step}"
        if step == "requeue":
            self._avoid[task_id] = task.robot_id
            return self._requeue(task, reason, "recovery", wall, stop_robot=True)
        law = self._other_law(task) if step == "flip" else task.law
        if step == "flip" and by_post and (alone or not task.route):
            self._wide_way.add(task_id)
            reason += " (routed round the posts' Eq. (27) zones)"
        elif step == "flip" and task.route:
            self._own_way.add(task_id)
            reason += " (off its route: the law's own way)"
        return self._held_revision(task, law, reason, "recovery", now, wall)

    def robot_removed(self, robot_id: str, wall: float) -> Effects:
        """The robot was removed from the fleet: queued tasks naming it fail (it will not
        come back to take them). Call only when it has no task under way."""
        assert robot_id not in self._robot_task
        self._version += self._held.pop(robot_id, None) is not None
        self._version += self.zones.release_robot(robot_id)
        effects: Effects = []
        for task in [t for t in self._queued.values() if t.request.robot_id == robot_id]:
            reason = f"robot {robot_id} was removed from the fleet"
            effects += self._finish(task, TaskStatus.FAILED, reason, wall, False)
        return effects

    def timeouts(self, now: float, wall: float) -> Effects:
        """Tasks under way past their deadline fail, and their robots are told to stop (a
        task whose robot an operator holds has no running deadline)."""
        effects: Effects = []
        late = [
            t
            for t in self._under_way.values()
            if self._tracking[t.id].deadline <= now and self._tracking[t.id].held_at is None
        ]
        for task in late:
            reason = f"timeout: not arrived within {self.config.task_timeout_s:g} s"
            effects += self._finish(task, TaskStatus.FAILED, reason, wall, True)
        return effects

    def resends(self, now: float) -> Effects:
        """Assignments not acknowledged yet (by a state with the task id and at least its
        revision) are sent again every ``resend_interval_s``."""
        effects: Effects = []
        interval = self.config.resend_interval_s
        for task in self._under_way.values():
            track = self._tracking[task.id]
            if track.seen_revision < task.revision and now - track.sent_at >= interval:
                track.sent_at = now
                effects.append(Publish(assignment_of(task, self.config.avoidance)))
        return effects
