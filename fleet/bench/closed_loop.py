"""An offline fleet: robots in the batch simulator, their tasks in the service's own ledger.

Used by ``parkfleet bench plan`` to make scenes with robots under way and to compare
planners on the same scenarios without Zenoh or processes. The robots are the simulator's
(the agents' control step with its safety filter, wheel limits, Eq. (27) repulsion from
every peer and static obstacle). The tasks live in a :class:`fleet.service.ledger.TaskLedger`
configured as the service configures it (:func:`fleet.service.ledger.ledger_config`; the
scenario's site map, and the single-robot zones the service holds,
:func:`fleet.service.zones.fleet_zones`: the site's and the narrow passages of its walls
and posts), so the offline fleet predicts what the service does:

* tasks are added to the ledger when they arrive (``direction`` the policy: ``auto``, or
  the fixed law a user would ask for);
* the planner gets the service's snapshot (:func:`fleet.service.snapshot.planning_input`
  with every fact the service takes from its ledger, lead time 0: no delivery delay) when
  tasks arrive or finish, when the previous plan asked for it (held robots,
  ``Plan.replan_in_s``), when a robot leaves its corridor (the ledger's check) and every
  ``replan_period_s``; its decisions go through
  :meth:`TaskLedger.apply` (stale status family or revision, unsafe plans dropped);
* the robots drive what the ledger publishes (each :class:`ParkAssignment` from the moment
  it is published, its start delay in simulated time, along its route's via-points as the
  agent drives them: a new revision's route from its first) and report states the ledger
  observes (acknowledgement, arrival, corridor).

Fixed policies (``cw``, ``ccw``) pair queued tasks with robots the planner's way
(:func:`fleet.core.planner.assign.pair_queued`) and assign them through the ledger, every
robot at once with that law: the robots' own avoidance only. Operator controls, stuck
recoveries and task timeouts are not exercised (the run's time limit ends it).

Metrics are the fleet benchmark's (:class:`fleet.bench.metrics.RunMetrics`, fed every
simulated tick): success, collisions, minimum separation, makespan (the time limit when a
task did not arrive) and path ratio per task that arrived; per planner call its wall time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fleet.bench.metrics import RunMetrics, RunResult
from fleet.bench.scenarios import Scenario, random_yard
from fleet.core.params import Avoidance, RobotProfile, SafetyConfig, Tolerance
from fleet.core.planner import Plan, PlannerConfig, PlanningSnapshot, TaskDecision
from fleet.core.planner.assign import pair_queued
from fleet.core.planner.rollout import STANDING_DELAY
from fleet.core.simulate import BatchProblem, batch_filter, obstacle_columns, simulate
from fleet.core.tasks import DEFAULT_GAINS, RobotStatus, Task, TaskRequest
from fleet.core.types import FloatArray, Law, Posture
from fleet.core.wire import (
    DEFAULT_PASS_M,
    CancelAssignment,
    ParkAssignment,
    Pose,
    RobotMode,
    RobotState,
)
from fleet.io.settings import Settings
from fleet.io.trace import TraceChunk
from fleet.service.effects import Effects, Publish, StoreWrite
from fleet.service.ledger import Outcome, TaskLedger, ledger_config
from fleet.service.snapshot import PlanInput, RobotFacts, planning_input
from fleet.service.zones import fleet_zones, zone_bodies

Planner = Callable[[PlanningSnapshot], Plan]
_STAND = Tolerance(position=1e-3, heading=1e-3)
#: Mode names of the offline fleet's ticks (:class:`RunMetrics` codes are their indices).
MODES: tuple[str, ...] = tuple(m.value for m in RobotMode)
_CODE = {m: np.uint8(k) for k, m in enumerate(RobotMode)}


@dataclass
class _Order:
    """What a simulated robot was last told and when [s, simulated]."""

    assignment: ParkAssignment
    received_at: float
    arrived_at: float | None = None
    passed: int = 0  # via-points of its route passed (a new revision starts at its first)


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
    outcomes: dict[Outcome, int]  # what became of the decisions (ledger.apply)


class OfflineFleet:
    """The robots and tasks of one scenario: simulated robots, the service's ledger."""

    def __init__(
        self,
        scenario: Scenario,
        *,
        direction: Law | None = None,
        arrivals: Sequence[float] | None = None,
        profile: RobotProfile | None = None,
        avoidance: Avoidance | None = None,
        separation: float = 0.5,
        dt: float = 0.02,
        safety: SafetyConfig | None = None,
    ) -> None:
        self.scenario = scenario
        self.settings = Settings(
            profile=profile or RobotProfile(),
            avoidance=avoidance or Avoidance(),
            safety=safety or SafetyConfig(),
            safety_separation_m=separation,
            control_rate_hz=1.0 / dt,
            yard=scenario.bounds,
        )
        site = scenario.site()
        if site is not None:  # its single-robot zones and lanes, as the service runs it
            self.settings = self.settings.with_site(site)
        self.profile = self.settings.profile
        self.dt = dt
        self.ledger = TaskLedger(ledger_config(self.settings), site=self.settings.site)
        obstacles = scenario.static_obstacles()  # the zones the service holds (a corridor)
        self.ledger.zones.set_zones(
            fleet_zones(self.settings, obstacles), zone_bodies(self.settings, obstacles)
        )
        self.tasks: dict[str, Task] = {}  # every task's latest version (the "store")
        self.orders: dict[str, _Order] = {}  # robot -> its last assignment
        self.outcomes: dict[Outcome, int] = dict.fromkeys(Outcome, 0)
        self.off_corridor = False  # a robot left its corridor since the last plan
        self.ids = scenario.robot_ids
        self._index = {rid: i for i, rid in enumerate(self.ids)}
        self.pose = np.array(scenario.starts, dtype=np.float64).reshape(-1, 3)
        self.t = 0.0
        self._ticks = 0  # control ticks simulated: the robots' state seq
        self._chunks = [self._chunk(np.array([0.0]), self.pose[None], self._modes()[None])]
        if arrivals is None:
            arrivals = [r.arrival_s for r in scenario.robots]
        gains = scenario.law_gains
        self._pending = sorted(
            (
                (
                    float(a),
                    f"t{j + 1}",
                    TaskRequest(
                        goal=Pose(x=g[0], y=g[1], theta=g[2]),
                        robot_id=self.ids[j] if scenario.named else None,
                        direction=direction or "auto",
                        tolerance=scenario.tolerance,
                        law_gains=dict(gains) if gains else None,
                    ),
                )
                for j, (g, a) in enumerate(zip(scenario.goals, arrivals, strict=True))
            ),
            key=lambda p: p[0],
        )
        self.task_count = len(self._pending)
        self.first_arrival = self._pending[0][0] if self._pending else 0.0

    # -- tasks and states ------------------------------------------------------------------

    def submit_arrived(self) -> int:
        """Put the tasks whose arrival time has come into the ledger; how many."""
        n = 0
        while self._pending and self._pending[0][0] <= self.t + 1e-9:
            at, task_id, request = self._pending.pop(0)
            task = Task(id=task_id, request=request, created_at=at, updated_at=at)
            self.tasks[task_id] = task
            self._run(self.ledger.add(task))
            n += 1
        return n

    def next_arrival(self) -> float:
        """When the next task arrives [s, simulated] (inf: none left)."""
        return self._pending[0][0] if self._pending else math.inf

    @property
    def finished(self) -> bool:
        """Every task submitted and final."""
        return not self._pending and not self.ledger.active

    def _run(self, effects: Effects) -> None:
        """Carry out the ledger's effects: store task versions, deliver messages."""
        for effect in effects:
            if isinstance(effect, StoreWrite):
                self.tasks[effect.task.id] = effect.task
            elif isinstance(effect, Publish):
                msg = effect.message
                if isinstance(msg, ParkAssignment):
                    old = self.orders.get(msg.robot_id)
                    if old is None or (old.assignment.task_id, old.assignment.revision) != (
                        msg.task_id,
                        msg.revision,
                    ):  # a re-send of the same revision changes nothing (as in the agent)
                        self.orders[msg.robot_id] = _Order(msg, self.t)
                elif isinstance(msg, CancelAssignment):
                    order = self.orders.get(msg.robot_id)
                    if order is not None and order.assignment.task_id == msg.task_id:
                        del self.orders[msg.robot_id]

    def _mode(self, robot_id: str) -> RobotMode:
        order = self.orders.get(robot_id)
        if order is None:
            return RobotMode.IDLE
        if order.arrived_at is not None:
            return RobotMode.ARRIVED
        a = order.assignment
        if a.hold or self.t < order.received_at + a.start_delay_s - 1e-9:
            return RobotMode.WAITING
        return RobotMode.DRIVING

    def _modes(self) -> np.ndarray:
        return np.array([_CODE[self._mode(rid)] for rid in self.ids], dtype=np.uint8)

    def state(self, robot_id: str) -> RobotState:
        """What the robot would publish now."""
        x, y, theta = (float(v) for v in self.pose[self._index[robot_id]])
        order = self.orders.get(robot_id)
        a = None if order is None else order.assignment
        return RobotState(
            robot_id=robot_id,
            seq=self._ticks,
            stamp=self.t,
            pose=Pose(x=x, y=y, theta=theta),
            mode=self._mode(robot_id),
            task_id=None if a is None else a.task_id,
            revision=0 if a is None else a.revision,
            law=None if a is None else a.law,
            radius=self.profile.radius,
        )

    def observe(self, wall: dict[str, float] | None = None) -> None:
        """Every robot's state to the ledger (``wall``: a robot's own report time [s],
        e.g. the instant it arrived within the last step)."""
        for rid in self.ids:
            when = (wall or {}).get(rid, self.t)
            seen = self.ledger.observe(self.state(rid), self.t, when)
            self.off_corridor |= seen.off_corridor
            self._run(seen.effects)

    # -- snapshot and decisions ------------------------------------------------------------

    def snapshot(self) -> PlanInput:
        """What the service would give the planner now (and the plan's origin seqs)."""
        robots = []
        busy = self.ledger.robot_task
        for rid in self.ids:
            state = self.state(rid)
            robots.append(
                RobotFacts(
                    state=state,
                    status=RobotStatus.from_mode(state.mode),
                    age_s=0.0,
                    available=rid not in busy,
                )
            )
        return planning_input(  # the service's snapshot, lead time 0
            self.ledger.version,
            robots,
            list(self.ledger.active.values()),
            self.scenario.static_obstacles(),
            self.settings,
            lead_time_s=0.0,
            time_scale=1.0,
            facts=self.ledger.facts(self.t),
        )

    def apply(self, plan: Plan, work: PlanInput) -> None:
        """Apply a plan's decisions through the ledger, as the service does."""
        relaxed = next((n for n in plan.notes if n.startswith("standstill")), None)
        for d in plan.decisions:
            self._decide(d, plan.safe, work.origin_seqs.get(d.robot_id), relaxed)
        self.off_corridor = False
        self.observe()  # the robots report at once: no delivery delay

    def _decide(
        self, d: TaskDecision, safe: bool, origin_seq: float | None, relaxed: str | None
    ) -> None:
        outcome, effects = self.ledger.apply(
            d,
            robot_available=d.robot_id not in self.ledger.robot_task,
            plan_safe=safe,
            origin_seq=origin_seq,
            now=self.t,
            wall=self.t,
            relaxed=relaxed,
        )
        self.outcomes[outcome] += 1
        if outcome is Outcome.APPLIED:
            self._run(effects)

    def assign_fixed(self, law: Law) -> None:
        """A fixed policy: queued tasks get robots and go at once with ``law``."""
        work = self.snapshot()
        for task, robot in pair_queued(work.snapshot, PlannerConfig()):
            decision = TaskDecision(task.task_id, robot.robot_id, "assign", law, task.revision)
            self._decide(decision, True, None, None)
        self.observe()

    # -- time ------------------------------------------------------------------------------

    def step(self, duration: float) -> bool:
        """Simulate ``duration`` [s] (less if every robot stands); True if a task finished."""
        n = len(self.ids)
        goal = self.pose.copy()
        gains = np.tile(DEFAULT_GAINS["ccw"].as_tuple(), (n, 1))  # standing rows: any gains
        cw = np.zeros(n, dtype=bool)
        tol: list[Tolerance] = [_STAND] * n
        delay = np.full(n, STANDING_DELAY)  # robots without a task never move
        routes: list[FloatArray | None] = [None] * n
        pass_m = np.full(n, DEFAULT_PASS_M)
        moving: list[int] = []
        for rid, order in self.orders.items():
            a = order.assignment
            if order.arrived_at is not None or a.hold:
                continue
            i = self._index[rid]
            moving.append(i)
            goal[i] = a.goal.as_tuple()
            gains[i] = a.gains.as_tuple()
            cw[i] = a.law == "cw"
            tol[i] = a.tolerance
            delay[i] = max(0.0, order.received_at + a.start_delay_s - self.t)
            routes[i] = np.array(a.route[order.passed :], dtype=np.float64).reshape(-1, 2)
            pass_m[i] = a.pass_m
        if not moving:
            self.t += duration
            return False
        problem = BatchProblem.build(
            self.pose,
            goal,
            gains,
            cw,
            tolerance=tol,
            profile=self.profile,
            **obstacle_columns(self.scenario.static_obstacles()),
            k_avoid=self.settings.avoidance.k_avoid,
            peer_radius=self.settings.avoidance.peer_radius,
            min_x_oa=self.settings.avoidance.min_x_oa,
            smoothing=self.settings.avoidance.smoothing_m,
            safety=batch_filter(self.settings.safety),
            start_delay=delay,
            routes=routes,
            pass_radius=pass_m,
        )
        result = simulate(problem, dt=self.dt, max_time=duration, record=True)
        assert result.trajectory is not None
        steps = max(result.steps, 1)
        ticks = self.t + self.dt * np.arange(1, steps + 1)
        modes = np.repeat(self._modes()[None], steps, axis=0)
        arrived: dict[str, float] = {}
        for i in moving:
            rid = self.ids[i]
            order = self.orders[rid]
            if result.passed is not None:
                order.passed += int(result.passed[i])
            start = order.received_at + order.assignment.start_delay_s
            modes[ticks < start - 1e-9, i] = _CODE[RobotMode.WAITING]
            modes[ticks >= start - 1e-9, i] = _CODE[RobotMode.DRIVING]
            if result.done[i]:
                at = self.t + float(result.time[i])
                modes[ticks >= at - 1e-9, i] = _CODE[RobotMode.ARRIVED]
                order.arrived_at = arrived[rid] = at
        poses = result.trajectory.poses[1 : steps + 1]
        if len(poses) < steps:  # a batch that stands still at once records no step
            poses = np.repeat(result.final_pose[None], steps, axis=0)
        self._chunks.append(self._chunk(ticks, poses, modes))
        self.pose = result.final_pose.copy()
        self._ticks += steps
        self.t += steps * self.dt
        self.observe(arrived)
        return bool(arrived)

    @staticmethod
    def _chunk(t: np.ndarray, poses: np.ndarray, modes: np.ndarray) -> TraceChunk:
        return TraceChunk(t=t, poses=np.array(poses, dtype=np.float64), modes=modes)

    # -- metrics ---------------------------------------------------------------------------

    def metrics(self) -> RunResult:
        """The fleet benchmark's figures of the run so far (every simulated tick)."""
        n = len(self.ids)
        goals = np.full((n, 3), np.nan)
        legs = []
        for task in sorted(self.tasks.values(), key=lambda t: t.created_at):
            if task.robot_id is None:
                continue
            i = self._index[task.robot_id]
            g = task.request.goal
            goals[i] = g.as_tuple()  # a robot's last task
            legs.append((i, g.x, g.y))
        metrics = RunMetrics(
            [self.profile.radius] * n,
            goals,
            self.scenario.static_obstacles(),
            MODES,
            t_start=self.first_arrival,
            tasks=legs,
        )
        for chunk in self._chunks:
            metrics.add(chunk)
        return metrics.result()


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
    if policy not in ("auto", "cw", "ccw"):
        raise ValueError(f"unknown policy {policy!r}: auto, cw or ccw")
    if policy == "auto" and planner is None:
        raise ValueError("policy auto needs a planner")
    fixed: Law | None = None if policy == "auto" else ("cw" if policy == "cw" else "ccw")
    fleet = OfflineFleet(scenario, direction=fixed, arrivals=arrivals, dt=dt)
    walls: list[float] = []
    rollouts: list[int] = []
    clusters: list[int] = []
    snaps: list[PlanningSnapshot] = []
    waiting_max = 0
    next_plan = 0.0
    while fleet.t < time_limit_s and not fleet.finished:
        trigger = fleet.submit_arrived() > 0 or fleet.t >= next_plan - 1e-9
        if planner is not None:
            trigger = trigger or fleet.off_corridor
        if trigger:
            if planner is not None:
                work = fleet.snapshot()
                if keep_snapshots:
                    snaps.append(work.snapshot)
                began = time.perf_counter()
                result = planner(work.snapshot)
                walls.append(time.perf_counter() - began)
                rollouts.append(result.rollouts)
                clusters.append(result.clusters)
                waiting_max = max(waiting_max, result.waiting)
                fleet.apply(result, work)
                retry = result.replan_in_s if result.replan_in_s is not None else math.inf
                next_plan = fleet.t + min(replan_period_s, retry)
            else:
                assert fixed is not None
                fleet.assign_fixed(fixed)
                next_plan = fleet.t + replan_period_s
        upcoming = fleet.next_arrival()
        horizon = min(next_plan, upcoming) - fleet.t
        if fleet.step(max(horizon, dt)):
            next_plan = fleet.t  # a robot is free: plan again now
    run = fleet.metrics()
    tasks = fleet.task_count
    ratio = run.path_ratio()
    return ClosedLoopResult(
        scenario=scenario.name,
        policy=policy,
        robots=len(fleet.ids),
        success_rate=run.success_count() / tasks if tasks else 1.0,
        collisions=run.collision_pairs,
        min_separation_m=math.inf if run.min_separation_m is None else run.min_separation_m,
        makespan_s=run.makespan(tasks, time_limit_s),
        path_ratio=math.nan if ratio is None else ratio,
        plan_wall_s=walls,
        plan_rollouts=rollouts,
        plan_clusters=clusters,
        waiting_max=waiting_max,
        snapshots=snaps,
        outcomes=dict(fleet.outcomes),
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
            "walls": [
                w.model_copy(update={"points": [(x, -y) for x, y in w.points]})
                for w in scenario.walls
            ],
        }
    )


def yard(n: int, seed: int) -> Scenario:
    """``n`` robots and ``n`` unnamed goals at random in a square yard of one robot per
    10 m^2 (10 robots: 10 m x 10 m; 200 robots: 44.7 m x 44.7 m, the service's yard
    widened to fit): the fleet bench's random yards."""
    return random_yard(n, seed)


def arrival_times(n: int, seed: int, mean_gap_s: float) -> list[float]:
    """Arrival times [s] of ``n`` tasks: the first at 0, then a Poisson stream."""
    gaps = np.random.default_rng(seed).exponential(mean_gap_s, size=n)
    gaps[0] = 0.0
    return [float(t) for t in np.cumsum(gaps)]


__all__ = [
    "ClosedLoopResult",
    "OfflineFleet",
    "Planner",
    "arrival_times",
    "mirrored",
    "run_closed_loop",
    "yard",
]
