"""The planner's input, built from what the service copied under its lock (pure).

The shell copies references under its lock -- one :class:`RobotFacts` per robot with a known
pose (not those taken out of the yard: lost and decommissioned), the active tasks, the
obstacles, the robots an operator holds still and the tasks taken from stuck robots -- and
:func:`planning_input` turns them into the
immutable :class:`fleet.core.planner.PlanningSnapshot` *outside* the lock. It also keeps,
per robot, the state sequence number at which the plan's time starts (``origin_seqs``: the
snapshot's seq plus the lead time in control ticks), so the service can compare observed
poses with the predicted corridors at the same robot time.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

from fleet.core.params import RobotProfile
from fleet.core.planner.assign import plannable
from fleet.core.planner.model import PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.route import lane_shapes
from fleet.core.tasks import RobotStatus, Task, TaskStatus
from fleet.core.types import LAWS, Law
from fleet.core.wire import Obstacle, RobotState
from fleet.core.zones import ZonePass, ZoneShape
from fleet.io.settings import Settings


@dataclass(frozen=True, slots=True)
class RobotFacts:
    """One robot as copied under the service lock."""

    state: RobotState
    status: RobotStatus
    age_s: float  # since its state arrived [s, service clock]
    available: bool  # may take a new task (not lost, no task, in service, not held)
    profile: RobotProfile | None = None  # its own (described); None: the host's [profile]


@dataclass(frozen=True)
class LedgerFacts:
    """What a plan needs from the task ledger beside its tasks, copied (safe to use once the
    service's lock is released; :meth:`fleet.service.ledger.TaskLedger.facts` makes it, for
    the service and the offline fleet alike). ``held``: robots an operator holds still
    (their tasks stand, ``hold``); ``avoided``: queued task -> the stuck robot it was taken
    from; ``acknowledged_s``: task under way -> how long ago [s, the ledger's clock] its
    robot first reported the current revision (so the planner knows how much of the start
    delay is left, in robot time); ``pinned``: task under way -> the law a stuck recovery
    chose (the planner may only use it); ``own_way``: tasks under way a stuck recovery took
    off their route (the planner routes them no more); ``wide_way``: tasks under way a stuck
    recovery sent round the posts' Eq. (27) zones; ``gave_way``: tasks whose robot gave way
    in a standoff (held: the others are routed round it); ``round_robots``: task under way
    -> the standing robots that held its robot off in a standoff (it is routed round them);
    ``zones``: the single-robot zones, ``zone_holders``: zone -> robot -> its pass, the
    robots holding each."""

    held: Collection[str] = frozenset()
    avoided: Mapping[str, str] = field(default_factory=dict)
    acknowledged_s: Mapping[str, float] = field(default_factory=dict)
    pinned: Mapping[str, Law] = field(default_factory=dict)
    own_way: Collection[str] = frozenset()
    wide_way: Collection[str] = frozenset()
    gave_way: Collection[str] = frozenset()
    round_robots: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    zones: Sequence[ZoneShape] = ()
    zone_holders: Mapping[str, Mapping[str, ZonePass | None]] = field(default_factory=dict)


@dataclass(frozen=True)
class PlanInput:
    """A snapshot for the planner and what the service needs to apply its plan."""

    snapshot: PlanningSnapshot
    origin_seqs: dict[str, float]  # robot -> state seq at t = 0 of the plan


def worth_planning(robots: Sequence[RobotFacts], tasks: Sequence[Task]) -> bool:
    """Whether a plan could decide anything: a queued task and an available robot (its
    own, if it names one), or a task under way."""
    if any(t.status.under_way for t in tasks):
        return True
    available = {r.state.robot_id for r in robots if r.available}
    if not available:
        return False
    return any(
        t.status is TaskStatus.QUEUED
        and (t.request.robot_id is None or t.request.robot_id in available)
        for t in tasks
    )


def _task_snapshot(task: Task, facts: LedgerFacts, running_s: Mapping[str, float]) -> TaskSnapshot:
    request = task.request
    under_way = task.status.under_way
    return TaskSnapshot(
        task_id=task.id,
        goal=request.goal.as_tuple(),
        direction=facts.pinned.get(task.id, request.direction),
        gains={law: request.gains_for(law) for law in LAWS},
        tolerance=request.tolerance,
        status=task.status,
        created_at=task.created_at,
        named_robot=request.robot_id,
        robot_id=task.robot_id if under_way else None,
        law=task.law,
        revision=task.revision,
        hold=task.hold or (under_way and task.robot_id in facts.held),
        start_delay_s=task.start_delay_s,
        route=tuple(task.route) if under_way else (),
        own_way=under_way and task.id in facts.own_way,
        wide_way=under_way and task.id in facts.wide_way,
        gave_way=under_way and task.hold and task.id in facts.gave_way,
        round_robots=facts.round_robots.get(task.id, ()) if under_way else (),
        avoid_robot=facts.avoided.get(task.id),
        start_delay_left_s=(
            max(0.0, task.start_delay_s - running_s[task.id]) if task.id in running_s else None
        ),
    )


def planning_input(
    version: int,
    robots: Sequence[RobotFacts],
    tasks: Sequence[Task],
    obstacles: Sequence[Obstacle],
    settings: Settings,
    lead_time_s: float,
    time_scale: float,
    facts: LedgerFacts | None = None,
) -> PlanInput:
    """The planner's snapshot (robots sorted by id, tasks oldest first): the tasks under
    way and, of the queued ones, those a plan may pair with the available robots
    (:func:`~fleet.core.planner.assign.plannable`: as many as there are robots to take
    them, not the thousands a burst may queue; the plan is the same); ``facts``: what the
    ledger knows of them beside (:class:`LedgerFacts`; None: nothing)."""
    facts = facts or LedgerFacts()
    hz = settings.control_rate_hz
    available = {r.state.robot_id for r in robots if r.available}
    queued = [t for t in tasks if t.status is TaskStatus.QUEUED]
    tasks = [t for t in tasks if t.status is not TaskStatus.QUEUED]
    if available and queued:
        queued.sort(key=lambda t: t.created_at)
        tasks += plannable(queued, available, lambda t: t.request.robot_id)
    running = {tid: ago * time_scale for tid, ago in facts.acknowledged_s.items()}
    robot_snaps = []
    origins: dict[str, float] = {}
    for r in sorted(robots, key=lambda r: r.state.robot_id):
        s = r.state
        robot_snaps.append(
            RobotSnapshot(
                robot_id=s.robot_id,
                pose=s.pose.as_tuple(),
                status=r.status,
                available=r.available,
                task_id=s.task_id,
                law=s.law,
                revision=s.revision,
                age_s=r.age_s * time_scale,
                profile=r.profile,
            )
        )
        origins[s.robot_id] = s.seq + lead_time_s * hz
    snapshot = PlanningSnapshot(
        version=version,
        robots=tuple(robot_snaps),
        tasks=tuple(
            _task_snapshot(t, facts, running) for t in sorted(tasks, key=lambda t: t.created_at)
        ),
        obstacles=tuple(obstacles),
        profile=settings.profile,
        avoidance=settings.avoidance,
        safety=settings.safety,
        separation_m=settings.safety_separation_m,
        lead_time_s=lead_time_s,
        control_dt=1.0 / hz,
        zones=tuple(facts.zones),
        lanes=() if settings.site is None else lane_shapes(settings.site.lanes),
        zone_holders=tuple(
            (zone, robot, how)
            for zone, held in sorted(facts.zone_holders.items())
            for robot, how in held.items()
        ),
    )
    return PlanInput(snapshot, origins)
