"""An offline fleet: robots in the batch simulator, tasks planned as the service plans them.

Used by ``parkfleet bench plan`` to make scenes with robots under way and to compare
planners on the same scenarios without Zenoh or processes. The robots are the simulator's
(the agents' control step, wheel limits, Eq. (27) repulsion from every peer and static
obstacle); the planner is called on a :class:`~fleet.core.planner.PlanningSnapshot` the way
the fleet service calls it:

* when tasks arrive or finish, when the previous plan asked for it (held robots,
  ``Plan.replan_in_s``), when a robot leaves its corridor, and every ``replan_period_s``;
* its decisions are applied at once (``lead_time_s`` = 0: no delivery delay): ``assign``
  gives a queued task its robot, law, start delay or hold; ``revise`` replaces them as
  ``revision + 1`` when the task still has the revision the decision was made from;
  ``keep`` only refreshes the corridor.

Fixed policies (``cw``, ``ccw``) assign the same way (:func:`fleet.core.planner.assign.
pair_queued`) and start every robot at once with that law: the robots' own avoidance only.

Metrics, as the fleet benchmark defines them: success, collisions (pairs of robots closer
than two body radii), minimum separation between any two robots [m], makespan (from the
first submission until the last task finished [s]), path ratio (distance driven / straight
line, mean over tasks), and per planner call its wall time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fleet.bench.scenarios import Scenario, random_yard
from fleet.core.params import Avoidance, RobotProfile, SafetyConfig, Tolerance
from fleet.core.planner import Plan, PlannerConfig, PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.planner.assign import pair_queued
from fleet.core.planner.corridor import left_corridor
from fleet.core.planner.rollout import STANDING_DELAY
from fleet.core.simulate import BatchProblem, batch_filter, simulate
from fleet.core.tasks import DEFAULT_GAINS, Direction, RobotStatus, TaskStatus
from fleet.core.types import LAWS, Law, Posture

Planner = Callable[[PlanningSnapshot], Plan]
_STAND = Tolerance(position=1e-3, heading=1e-3)


@dataclass
class _Task:
    task_id: str
    goal: Posture
    arrival: float
    named: str | None
    status: TaskStatus = TaskStatus.QUEUED
    robot_id: str | None = None
    law: Law | None = None
    revision: int = 0
    hold: bool = False
    delay: float = 0.0
    applied_at: float = 0.0
    corridor: tuple[tuple[float, float, float], ...] = ()
    corridor_at: float = 0.0
    finished_at: float | None = None
    start_xy: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class ClosedLoopResult:
    """One scenario under one policy (see the module docstring)."""

    scenario: str
    policy: str
    robots: int
    success_rate: float
    collisions: int
    min_separation_m: float
    makespan_s: float
    path_ratio: float
    plan_wall_s: list[float]
    plan_rollouts: list[int]
    plan_clusters: list[int]
    waiting_max: int
    snapshots: list[PlanningSnapshot]


class OfflineFleet:
    """The robots and tasks of one scenario, stepped by the batch simulator."""

    def __init__(
        self,
        scenario: Scenario,
        *,
        arrivals: Sequence[float] | None = None,
        profile: RobotProfile | None = None,
        avoidance: Avoidance | None = None,
        separation: float = 0.5,
        dt: float = 0.02,
        safety: SafetyConfig | None = None,
    ) -> None:
        self.scenario = scenario
        self.profile = profile or RobotProfile()
        self.avoidance = avoidance or Avoidance()
        self.safety = safety or SafetyConfig()
        self.separation = separation
        self.dt = dt
        self.ids = scenario.robot_ids
        self.pose = np.array(scenario.starts, dtype=np.float64).reshape(-1, 3)
        self.distance = np.zeros(len(self.ids))
        self.t = 0.0
        self.version = 0
        self.min_pair = np.full((len(self.ids), len(self.ids)), np.inf)
        if arrivals is None:
            arrivals = [r.arrival_s for r in scenario.robots]
        arrivals = list(arrivals)
        self.tasks = [
            _Task(
                task_id=f"t{j + 1}",
                goal=g,
                arrival=a,
                named=self.ids[j] if scenario.named else None,
            )
            for j, (g, a) in enumerate(zip(scenario.goals, arrivals, strict=True))
        ]
        gains = scenario.law_gains or {}
        self.gains = {law: gains.get(law, DEFAULT_GAINS[law]) for law in LAWS}

    # -- snapshot and decisions -------------------------------------------------------------

    def _task_of(self, robot_id: str) -> _Task | None:
        for t in self.tasks:
            if t.robot_id == robot_id and not t.status.final:
                return t
        return None

    def snapshot(self, direction: Direction = "auto") -> PlanningSnapshot:
        """What the service would give the planner now."""
        robots = []
        for i, rid in enumerate(self.ids):
            task = self._task_of(rid)
            if task is None:
                status = RobotStatus.IDLE
            elif task.hold or self.t < task.applied_at + task.delay:
                status = RobotStatus.WAITING
            else:
                status = RobotStatus.DRIVING
            robots.append(
                RobotSnapshot(
                    robot_id=rid,
                    pose=(float(self.pose[i, 0]), float(self.pose[i, 1]), float(self.pose[i, 2])),
                    status=status,
                    available=task is None,
                    task_id=None if task is None else task.task_id,
                    law=None if task is None else task.law,
                    revision=0 if task is None else task.revision,
                )
            )
        tasks = []
        for t in self.tasks:
            if t.status.final or t.arrival > self.t + 1e-9:
                continue
            tasks.append(
                TaskSnapshot(
                    task_id=t.task_id,
                    goal=t.goal,
                    direction=direction,
                    gains=dict(self.gains),
                    tolerance=self.scenario.tolerance,
                    status=t.status,
                    created_at=t.arrival,
                    named_robot=t.named,
                    robot_id=t.robot_id,
                    law=t.law,
                    revision=t.revision,
                    hold=t.hold,
                    start_delay_s=t.delay,
                    start_delay_left_s=None
                    if t.robot_id is None
                    else max(0.0, t.applied_at + t.delay - self.t),
                )
            )
        return PlanningSnapshot(
            version=self.version,
            robots=tuple(robots),
            tasks=tuple(tasks),
            obstacles=tuple(o.as_obstacle() for o in self.scenario.obstacles),
            profile=self.profile,
            avoidance=self.avoidance,
            safety=self.safety,
            separation_m=self.separation,
            control_dt=self.dt,
        )

    def apply(self, result: Plan) -> None:
        """Apply a plan's decisions (stale ones dropped by revision)."""
        by_id = {t.task_id: t for t in self.tasks}
        for d in result.decisions:
            task = by_id.get(d.task_id)
            if task is None or task.status.final:
                continue
            if d.action == "assign":
                if task.status != TaskStatus.QUEUED or self._task_of(d.robot_id) is not None:
                    continue
                task.robot_id = d.robot_id
                task.status = TaskStatus.ASSIGNED
                task.start_xy = tuple(self.pose[self.ids.index(d.robot_id), :2])
            elif d.action == "revise":
                if task.robot_id != d.robot_id or task.revision != d.revision:
                    continue
                task.revision += 1
            else:
                task.corridor, task.corridor_at = d.corridor, self.t
                continue
            task.law, task.hold, task.delay = d.law, d.hold, d.start_delay_s
            task.applied_at = self.t
            task.status = TaskStatus.WAITING if d.hold else TaskStatus.DRIVING
            task.corridor, task.corridor_at = d.corridor, self.t
        self.version += 1

    def assign_fixed(self, law: Law) -> None:
        """A fixed policy: queued tasks get robots and go at once with ``law``."""
        for task, robot in pair_queued(self.snapshot(law), PlannerConfig()):
            t = next(x for x in self.tasks if x.task_id == task.task_id)
            t.robot_id, t.law, t.status = robot.robot_id, law, TaskStatus.DRIVING
            t.applied_at = self.t
            t.start_xy = tuple(self.pose[self.ids.index(robot.robot_id), :2])
        self.version += 1

    # -- time -------------------------------------------------------------------------------

    def off_corridor(self, radius: float, slack: float) -> bool:
        for t in self.tasks:
            if t.status.final or t.robot_id is None or not t.corridor:
                continue
            i = self.ids.index(t.robot_id)
            x, y = float(self.pose[i, 0]), float(self.pose[i, 1])
            if left_corridor(t.corridor, self.t - t.corridor_at, x, y, radius, slack):
                return True
        return False

    def step(self, duration: float) -> bool:
        """Simulate ``duration`` [s] (less if every robot stands); True if a task finished."""
        n = len(self.ids)
        goal = self.pose.copy()
        gains = np.tile(self.gains["ccw"].as_tuple(), (n, 1))
        cw = np.zeros(n, dtype=bool)
        tol: list[Tolerance] = [_STAND] * n
        delay = np.full(n, STANDING_DELAY)  # robots without a task never move
        active: dict[int, _Task] = {}
        for t in self.tasks:
            if t.status.final or t.robot_id is None or t.hold or t.law is None:
                continue
            i = self.ids.index(t.robot_id)
            active[i] = t
            goal[i] = t.goal
            gains[i] = self.gains[t.law].as_tuple()
            cw[i] = t.law == "cw"
            tol[i] = self.scenario.tolerance
            delay[i] = max(0.0, t.applied_at + t.delay - self.t)
        if not active:
            self.t += duration
            return False
        problem = BatchProblem.build(
            self.pose,
            goal,
            gains,
            cw,
            tolerance=tol,
            profile=self.profile,
            obstacles=[(o.x, o.y) for o in self.scenario.obstacles],
            obstacle_radius=[o.radius for o in self.scenario.obstacles],
            obstacle_body=[o.body for o in self.scenario.obstacles],
            k_avoid=self.avoidance.k_avoid,
            peer_radius=self.avoidance.peer_radius,
            min_x_oa=self.avoidance.min_x_oa,
            safety=batch_filter(self.safety),
            start_delay=delay,
        )
        result = simulate(problem, dt=self.dt, max_time=duration, track_separation=True)
        assert result.min_pair_distance is not None
        np.minimum(self.min_pair, result.min_pair_distance, out=self.min_pair)
        self.pose = result.final_pose.copy()
        self.distance += result.distance
        finished = False
        for i, t in active.items():
            if result.done[i]:
                t.status = TaskStatus.SUCCEEDED
                t.finished_at = self.t + float(result.time[i])
                finished = True
        self.t += max(result.steps, 1) * self.dt
        return finished

    def result(self, policy: str) -> dict[str, float | int]:
        done = [t for t in self.tasks if t.status == TaskStatus.SUCCEEDED]
        ratios = []
        for t in self.tasks:
            if t.robot_id is None:
                continue
            straight = math.dist(t.start_xy, t.goal[:2])
            if straight > 0:
                ratios.append(float(self.distance[self.ids.index(t.robot_id)]) / straight)
        start = min(t.arrival for t in self.tasks)
        ends = [t.finished_at for t in done if t.finished_at is not None]
        min_sep = float(self.min_pair.min()) if len(self.ids) > 1 else math.inf
        contact = 2 * self.profile.radius
        iu = np.triu_indices(len(self.ids), 1)
        return {
            "success_rate": len(done) / len(self.tasks),
            "collisions": int(np.count_nonzero(self.min_pair[iu] < contact)),
            "min_separation_m": min_sep,
            "makespan_s": (max(ends) - start) if len(done) == len(self.tasks) else math.inf,
            "path_ratio": float(np.mean(ratios)) if ratios else math.nan,
        }


def run_closed_loop(
    scenario: Scenario,
    policy: str,
    planner: Planner | None = None,
    *,
    arrivals: Sequence[float] | None = None,
    replan_period_s: float = 2.0,
    time_limit_s: float = 240.0,
    keep_snapshots: bool = False,
    dt: float = 0.02,
) -> ClosedLoopResult:
    """Run ``scenario`` to the end under ``policy`` (``auto`` with ``planner``, or a law)."""
    fleet = OfflineFleet(scenario, arrivals=arrivals, dt=dt)
    walls: list[float] = []
    rollouts: list[int] = []
    clusters: list[int] = []
    snaps: list[PlanningSnapshot] = []
    waiting_max = 0
    next_plan, seen_arrivals = 0.0, -1
    arrivals = sorted({t.arrival for t in fleet.tasks})
    while fleet.t < time_limit_s and not all(t.status.final for t in fleet.tasks):
        arrived = sum(1 for a in arrivals if a <= fleet.t + 1e-9)
        trigger = arrived != seen_arrivals or fleet.t >= next_plan - 1e-9
        if policy == "auto":
            trigger = trigger or fleet.off_corridor(0.5, 2.0)
        if trigger:
            seen_arrivals = arrived
            if policy == "auto":
                assert planner is not None
                snap = fleet.snapshot()
                if keep_snapshots:
                    snaps.append(snap)
                began = time.perf_counter()
                result = planner(snap)
                walls.append(time.perf_counter() - began)
                rollouts.append(result.rollouts)
                clusters.append(result.clusters)
                waiting_max = max(waiting_max, result.waiting)
                fleet.apply(result)
                retry = result.replan_in_s if result.replan_in_s is not None else math.inf
                next_plan = fleet.t + min(replan_period_s, retry)
            else:
                fleet.assign_fixed("cw" if policy == "cw" else "ccw")
                next_plan = fleet.t + replan_period_s
        upcoming = [a for a in arrivals if a > fleet.t + 1e-9]
        horizon = min([next_plan, *upcoming[:1]]) - fleet.t
        if fleet.step(max(horizon, dt)):
            next_plan = fleet.t  # a robot is free: plan again now
    metrics = fleet.result(policy)
    return ClosedLoopResult(
        scenario=scenario.name,
        policy=policy,
        robots=len(fleet.ids),
        success_rate=float(metrics["success_rate"]),
        collisions=int(metrics["collisions"]),
        min_separation_m=float(metrics["min_separation_m"]),
        makespan_s=float(metrics["makespan_s"]),
        path_ratio=float(metrics["path_ratio"]),
        plan_wall_s=walls,
        plan_rollouts=rollouts,
        plan_clusters=clusters,
        waiting_max=waiting_max,
        snapshots=snaps,
    )


def mirrored(scenario: Scenario) -> Scenario:
    """The mirror image of ``scenario`` in the x axis (y -> -y, theta -> -theta): a swap of
    the other chirality."""

    def flip(p: Posture) -> Posture:
        return (p[0], -p[1], -p[2])

    return scenario.model_copy(
        update={
            "name": f"{scenario.name}-mirror",
            "robots": [
                r.model_copy(update={"start": flip(r.start), "goal": flip(r.goal)})
                for r in scenario.robots
            ],
            "obstacles": [o.model_copy(update={"y": -o.y}) for o in scenario.obstacles],
        }
    )


def yard(n: int, seed: int) -> Scenario:
    """``n`` robots and ``n`` unnamed goals at random in a square yard of one robot per
    10 m^2, within the service's 20 m x 20 m yard (10 robots: 10 m x 10 m; 50 robots:
    19 m x 19 m, one per 7.2 m^2): the fleet bench's random yards."""
    return random_yard(n, seed)


def arrival_times(n: int, seed: int, mean_gap_s: float) -> list[float]:
    """Arrival times [s] of ``n`` tasks: the first at 0, then a Poisson stream."""
    gaps = np.random.default_rng(seed).exponential(mean_gap_s, size=n)
    gaps[0] = 0.0
    return [float(t) for t in np.cumsum(gaps)]


def percentile(values: Sequence[float], q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else math.nan


__all__ = [
    "ClosedLoopResult",
    "OfflineFleet",
    "Planner",
    "arrival_times",
    "mirrored",
    "percentile",
    "run_closed_loop",
    "yard",
]
