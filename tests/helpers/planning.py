"""Scenes for the planner's tests, and an independent replay of a plan.

The replay is deliberately not the planner's rollout code: one plain simulator call for
the whole scene (every robot a peer of every other, no groups, padding or segments), built
from the snapshot and the decisions as the robots would apply them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.params import Tolerance
from fleet.core.planner import Plan, PlannerConfig, PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.planner.rollout import STANDING_DELAY
from fleet.core.simulate import BatchProblem, SimResult, batch_filter, obstacle_columns, simulate
from fleet.core.tasks import DEFAULT_GAINS, Direction, RobotStatus, TaskStatus
from fleet.core.types import Law, Posture

TOL = Tolerance(position=0.1, heading=0.1)
_STAND = Tolerance(position=1e-3, heading=1e-3)


def idle(rid: str, pose: Posture) -> RobotSnapshot:
    return RobotSnapshot(rid, pose, RobotStatus.IDLE, available=True)


def queued(
    tid: str, goal: Posture, robot: str | None, created: float = 0.0, direction: Direction = "auto"
) -> TaskSnapshot:
    return TaskSnapshot(
        task_id=tid,
        goal=goal,
        direction=direction,
        gains=dict(DEFAULT_GAINS),
        tolerance=TOL,
        status=TaskStatus.QUEUED,
        created_at=created,
        named_robot=robot,
    )


def scene(
    starts: Sequence[Posture],
    goals: Sequence[Posture],
    *,
    separation: float = 0.5,
    direction: Direction = "auto",
    dt: float = 0.05,
    version: int = 1,
) -> PlanningSnapshot:
    """Robots r0, r1, ... at ``starts``, each with a queued task naming it to its goal."""
    robots = tuple(idle(f"r{i}", s) for i, s in enumerate(starts))
    tasks = tuple(queued(f"t{i}", g, f"r{i}", float(i), direction) for i, g in enumerate(goals))
    return PlanningSnapshot(
        version=version, robots=robots, tasks=tasks, separation_m=separation, control_dt=dt
    )


def swap2(mirror: bool = False, separation: float = 0.5) -> PlanningSnapshot:
    """Two robots swapping sides head on, in one chirality or its mirror image."""
    s = -1.0 if mirror else 1.0
    starts = [(-3.0, 0.3 * s, s * 0.3), (3.0, -0.3 * s, math.pi - s * 0.3)]
    goals = [(3.0, 0.3 * s, s * 0.3), (-3.0, -0.3 * s, math.pi - s * 0.3)]
    return scene(starts, goals, separation=separation)


@dataclass(frozen=True)
class Replay:
    """The plan run by the simulator: every robot's arrival and the closest approaches."""

    result: SimResult
    moving: np.ndarray  # (n,) bool: robots that drive in the plan
    start_distance: np.ndarray  # (n, n) [m]

    def worst_shortfall(self, separation: float) -> float:
        """How far the worst pair involving a moving robot came inside its allowed
        distance (separation, or its start distance if closer) [m]; <= 0 is safe."""
        assert self.result.min_pair_distance is not None
        allowed = np.minimum(separation, self.start_distance - 1e-9)
        involved = self.moving[:, None] | self.moving[None, :]
        np.fill_diagonal(involved, False)
        if not involved.any():
            return -math.inf
        return float(np.max(np.where(involved, allowed - self.result.min_pair_distance, -np.inf)))


def replay(snapshot: PlanningSnapshot, result: Plan, max_time: float = 300.0) -> Replay:
    """Simulate ``snapshot``'s robots applying ``result`` (robots under way without a
    decision go on as the snapshot says; held robots and robots without a task stand)."""
    decisions = {d.robot_id: d for d in result.decisions}
    tasks = {t.task_id: t for t in snapshot.tasks}
    by_robot = {t.robot_id: t for t in snapshot.tasks if t.robot_id is not None}
    starts, goals, gains, laws, tols, delays, moving = [], [], [], [], [], [], []
    routes: list[tuple[tuple[float, float], ...]] = []
    for r in snapshot.robots:
        d = decisions.get(r.robot_id)
        task = tasks[d.task_id] if d is not None else by_robot.get(r.robot_id)
        law: Law | None = d.law if d is not None else (task.law if task is not None else None)
        hold = d.hold if d is not None else (task is None or task.hold)
        delay = d.start_delay_s if d is not None else (task.start_delay_s if task else 0.0)
        drives = task is not None and law is not None and not hold
        starts.append(r.pose)
        goals.append(task.goal if drives and task is not None else r.pose)
        gains.append(DEFAULT_GAINS[law or "ccw"])
        laws.append(law or "ccw")
        tols.append(task.tolerance if drives and task is not None else _STAND)
        delays.append(delay if drives else STANDING_DELAY)  # standing robots never move
        moving.append(drives)
        sent = d.route if d is not None else (task.route if task is not None else ())
        routes.append(sent if drives else ())
    obstacles = snapshot.obstacles
    avoid = snapshot.avoidance
    problem = BatchProblem.build(
        starts,
        goals,
        gains,
        laws,
        tolerance=tols,
        profile=[r.profile or snapshot.profile for r in snapshot.robots],
        **obstacle_columns(obstacles),
        k_avoid=avoid.k_avoid,
        peer_radius=avoid.peer_radius,
        min_x_oa=avoid.min_x_oa,
        smoothing=avoid.smoothing_m,
        start_delay=delays,
        safety=batch_filter(snapshot.safety),
        routes=routes,
        pass_radius=PlannerConfig().pass_m,
    )
    xy = np.array([s[:2] for s in starts])
    d0 = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    sim = simulate(problem, dt=snapshot.control_dt, max_time=max_time, track_separation=True)
    return Replay(sim, np.array(moving), d0)


def moved_on(snapshot: PlanningSnapshot, result: Plan, elapsed: float) -> PlanningSnapshot:
    """``snapshot`` ``elapsed`` seconds after its robots applied ``result``."""
    run = replay(snapshot, result, max_time=elapsed)
    decisions = {d.task_id: d for d in result.decisions}
    robots, tasks = [], []
    for i, (r, t) in enumerate(zip(snapshot.robots, snapshot.tasks, strict=True)):
        d = decisions[t.task_id]
        pose = tuple(float(v) for v in run.result.final_pose[i])
        status = RobotStatus.WAITING if elapsed < d.start_delay_s else RobotStatus.DRIVING
        robots.append(
            RobotSnapshot(r.robot_id, (pose[0], pose[1], pose[2]), status, False, t.task_id, d.law)
        )
        tasks.append(
            dataclasses.replace(
                t,
                status=TaskStatus.DRIVING,
                robot_id=d.robot_id,
                law=d.law,
                start_delay_s=d.start_delay_s,
                start_delay_left_s=max(0.0, d.start_delay_s - elapsed),
                route=d.route,
            )
        )
    return dataclasses.replace(
        snapshot, version=snapshot.version + 1, robots=tuple(robots), tasks=tuple(tasks)
    )
