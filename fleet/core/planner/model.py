"""What the planner reads and what it decides: pure, immutable data.

The fleet service takes a :class:`PlanningSnapshot` under its lock (cheap copies), runs
:func:`fleet.core.planner.plan` on its planner thread without the lock, and applies the
:class:`Plan` only if the tasks it decides on have not changed since (see
:class:`TaskDecision`). Times are robot seconds from the moment the plan reaches the robots
(``PlanningSnapshot.lead_time_s`` after the snapshot); poses are world-frame
``(x [m], y [m], theta [rad])``.

Decisions, per task (see :class:`TaskDecision`):

* ``assign`` -- a queued task gets a robot, a law, a start delay (the robot stands still
  that long after it receives the assignment, then drives) or ``hold`` (it stands still
  until a later revision: the planner found no safe option; the task is ``waiting``);
* ``revise`` -- a task under way gets ``revision + 1`` with a new law, delay or hold (a flip
  of the law, a hold, or a resume after a hold);
* ``keep`` -- nothing to send; the decision still carries the fresh corridor and arrival.

A plan never starts or resumes a robot it predicts unsafe: such robots hold, with the reason.
A robot whose way enters a single-robot zone another robot holds (or goes through first)
holds too, waiting for that zone (``TaskDecision.waits_for``); a decision that moves a robot
carries the zones it holds for it (``TaskDecision.zones``, :mod:`fleet.core.planner.gates`).

What the service does with a plan (the receding horizon):

* fill ``TaskSnapshot.start_delay_left_s`` for tasks under way (the delay still to wait);
  a robot reporting ``holding`` or ``lost`` is a standing obstacle (its task gets no
  decision), and so is every robot without a task;
* apply decisions whose ``revision`` still matches; send ``start_delay_s`` and ``hold``
  with the assignment (``ParkAssignment``); a held task is ``waiting`` with ``reason``;
* keep every decision's ``corridor`` (its ``t`` counts from when the plan was applied) and
  re-plan when a robot leaves it
  (:func:`~fleet.core.planner.corridor.left_corridor` with ``Plan.corridor_radius_m`` and
  ``Plan.corridor_slack_s``), when robots join, finish or are lost, after
  ``Plan.replan_in_s`` if set (held robots), and at a modest period; each call with robots
  under way costs about one rollout per cluster when nothing changed;
* count plans with ``waiting > 0`` (fallbacks) and plans that are not ``safe`` (only the
  lead-in can make one unsafe: robots under way already too close before the plan lands).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Literal

from fleet.core.params import Avoidance, Gains, RobotProfile, SafetyConfig, Tolerance
from fleet.core.route import LaneShape
from fleet.core.tasks import Direction, RobotStatus, TaskStatus
from fleet.core.types import Law, Posture
from fleet.core.wire import DEFAULT_PASS_M, Obstacle
from fleet.core.zones import ZonePass, ZoneShape

Action = Literal["assign", "revise", "keep"]


@dataclass(frozen=True)
class RobotSnapshot:
    """One robot as the service last saw it.

    ``available``: it may take a new task (known, not lost, no active task, in service).
    ``task_id``/``law``/``revision``: what its last state says it runs.
    ``age_s``: how old ``pose`` is [s, robot time] at the snapshot.
    ``profile``: the robot's own (it described itself); None: the snapshot's ``profile``
    (the host's, for a robot of an older release).
    """

    robot_id: str
    pose: Posture
    status: RobotStatus
    available: bool
    task_id: str | None = None
    law: Law | None = None
    revision: int = 0
    age_s: float = 0.0
    profile: RobotProfile | None = None


@dataclass(frozen=True)
class TaskSnapshot:
    """One active task: queued (``robot_id`` None) or under way (assigned, driving, waiting).

    ``gains`` holds the gains the robot would use with each law; ``named_robot`` is the robot
    the request names (None: the fleet chooses). ``law``, ``revision``, ``hold`` and
    ``start_delay_s`` are what was last sent (under way only); ``hold`` is also set while an
    operator holds its robot still (it stands). ``start_delay_left_s`` is how
    much of that start delay the robot still has to wait at the snapshot [s, robot time]
    (the service: ``max(0, start_delay_s - time since the revision was sent)``); None means
    unknown: the whole delay while the task is ``assigned`` or its robot reports
    ``waiting``, none otherwise.
    ``avoid_robot``: a queued task taken from this robot (it was stuck): give it to another
    robot if there is one. ``route``: the via-points its robot drives (the plan predicts
    the rest of them, :func:`fleet.core.route.remaining`, and keeps them unless it revises
    the task).
    """

    task_id: str
    goal: Posture
    direction: Direction
    gains: dict[Law, Gains]
    tolerance: Tolerance
    status: TaskStatus
    created_at: float
    named_robot: str | None = None
    robot_id: str | None = None
    law: Law | None = None
    revision: int = 0
    hold: bool = False
    start_delay_s: float = 0.0
    start_delay_left_s: float | None = None
    avoid_robot: str | None = None
    #: the via-points (x, y) [m] its robot was sent (under way only; empty: none)
    route: tuple[tuple[float, float], ...] = ()
    #: a stuck recovery took it off its route (its robot stalled on it): the plan gives it
    #: no via-points, its robot drives the law's own way (under way only)
    own_way: bool = False
    #: a stuck recovery found its robot stalled without a route: the plan routes it round
    #: the posts' Eq. (27) zones, not only their bodies (under way only)
    wide_way: bool = False
    #: its robot gave way in a standoff and stands until a plan resumes it: the plan sends
    #: the other movers round it, on their last leg too (under way and held only)
    gave_way: bool = False
    #: standing robots (ids) that held its robot off in a standoff: giving way to a robot
    #: that does not move changes nothing, so the plan sends it round them while they
    #: stand, on its last leg too (under way only)
    round_robots: tuple[str, ...] = ()


@dataclass(frozen=True)
class PlanningSnapshot:
    """Everything a plan depends on. ``version`` identifies the snapshot (the service
    increments it on every change it makes to tasks or robots)."""

    version: int
    robots: tuple[RobotSnapshot, ...]
    tasks: tuple[TaskSnapshot, ...]
    obstacles: tuple[Obstacle, ...] = ()
    profile: RobotProfile = field(default_factory=RobotProfile)  # robots without their own
    avoidance: Avoidance = field(default_factory=Avoidance)
    #: The safety filter the robots run (the rollouts run it too).
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    separation_m: float = 0.5  # minimum centre distance a plan must keep [m]
    lead_time_s: float = 0.0  # until the plan reaches the robots [s, robot time]
    control_dt: float = 0.02  # the agents' control period = Euler step [s]
    #: the single-robot zones (:mod:`fleet.core.zones`) and who holds them: (zone, robot,
    #: its pass; None: it stands in the zone)
    zones: tuple[ZoneShape, ...] = ()
    zone_holders: tuple[tuple[str, str, ZonePass | None], ...] = ()
    #: the site's lanes: routes follow them (:mod:`fleet.core.planner.lanes`)
    lanes: tuple[LaneShape, ...] = ()


@dataclass(frozen=True)
class TaskDecision:
    """What to do with one task (see the module docstring).

    ``revision`` is the task revision the decision was made from: the service applies it
    only if the task still has that revision (and the same robot and status family), else
    the decision is stale and dropped. ``corridor`` samples the predicted path
    ``(t [s], x [m], y [m])`` so the service can see when the robot leaves it
    (:func:`fleet.core.planner.corridor.left_corridor` with the plan's
    ``corridor_radius_m`` and ``corridor_slack_s``); ``t`` counts from the moment the plan
    reaches the robots. ``keep`` decisions carry a fresh corridor and arrival too.
    ``predicted_min_separation_m``: the closest predicted centre distance of this robot to
    any other over the plan (inf when none comes near) [m].
    """

    task_id: str
    robot_id: str
    action: Action
    law: Law
    revision: int = 0
    start_delay_s: float = 0.0
    hold: bool = False
    reason: str | None = None
    predicted_arrival_s: float | None = None
    corridor: tuple[tuple[float, float, float], ...] = ()
    predicted_min_separation_m: float = float("inf")
    #: via-points (x, y) [m] to pass before the goal (empty: straight to it) and their
    #: pass-through radius [m] (``ParkAssignment.route`` and ``pass_m``)
    route: tuple[tuple[float, float], ...] = ()
    pass_m: float = DEFAULT_PASS_M
    #: the robot is on the last leg of the route it was sent: ``route`` is empty because
    #: none of it is left, not because it is sent straight (no revision for that)
    last_leg: bool = False
    #: the passes through single-robot zones the robot holds for this decision (its way
    #: enters them; it starts or goes on only once it holds them):
    #: :mod:`fleet.core.planner.gates`
    zones: tuple[ZonePass, ...] = ()
    #: the zone a held robot waits for (another robot holds it, or goes first)
    waits_for: str | None = None


@dataclass(frozen=True)
class Plan:
    """A plan and how it was found."""

    snapshot_version: int
    decisions: tuple[TaskDecision, ...]
    safe: bool  # every robot it moves keeps ``separation_m`` in the prediction
    min_separation_m: float  # predicted, over pairs involving a moving robot [m]
    rollouts: int = 0  # closed-loop rollouts simulated
    clusters: int = 0  # independent groups of interacting robots searched
    waiting: int = 0  # robots held because no option was safe
    notes: tuple[str, ...] = ()
    #: [m] how far a robot may stray from its corridor before the service re-plans
    corridor_radius_m: float = 0.5
    #: [s] timing slack of the corridor check (a robot a little late or early is on it)
    corridor_slack_s: float = 2.0
    #: [s, robot time] re-plan after this long even without a trigger (robots hold and
    #: should be tried again); None: only on triggers and the service's own period
    replan_in_s: float | None = None

    def summary(self) -> dict[str, object]:
        """The plan in numbers, for the plans log (JSON-ready): decisions by action, robots
        held, robots it starts or keeps that it predicts short of their goals within its
        horizon (``short``: a jam shows here first), the search's size and its notes."""
        actions = dict(Counter(d.action for d in self.decisions))
        short = sum(1 for d in self.decisions if not d.hold and d.predicted_arrival_s is None)
        sep = self.min_separation_m
        return {
            "snapshot_version": self.snapshot_version,
            "decisions": len(self.decisions),
            "actions": actions,
            "held": sum(1 for d in self.decisions if d.hold),
            "short": short,
            "safe": self.safe,
            "min_separation_m": round(sep, 3) if sep != float("inf") else None,
            "rollouts": self.rollouts,
            "clusters": self.clusters,
            "notes": list(self.notes),
        }
