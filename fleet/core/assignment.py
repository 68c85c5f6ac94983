"""Optimal assignment of unnamed parking tasks to idle robots (pure).

Cost of robot i taking task j: the **predicted time to arrival** [s] of robot i driving
alone to goal j in a closed-loop rollout of the batch simulator (``fleet.core.simulate``,
the control code the robots run: law (17) and/or (20) with the task's gains and tolerance,
the wheel limits of the robot's own profile (one profile for all, or one per robot), static
obstacles with the Eq. (27) repulsion; peers are left out -- their interaction is the
planner's job, ``fleet.core.planner``). For an ``auto`` task the faster of the two laws
counts. A rollout that does not arrive within the horizon costs ``horizon + remaining
distance / top speed``, so unreachable pairs rank last but still rank by how far off they
end.

All pairs (and both laws) are simulated in one vectorised batch; with ``nearest`` = K only
the pairs of each task's K nearest robots and each robot's K nearest tasks are (a large
yard stays cheap), the others cost ``horizon + straight-line distance / top speed``, like a
pair that does not arrive. The assignment minimising the total cost is the Hungarian method
(``scipy.optimize.linear_sum_assignment``); with more tasks than robots only as many tasks
as robots are matched.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.params import Avoidance, Gains, RobotProfile, Tolerance
from fleet.core.simulate import BatchProblem, obstacle_columns, simulate
from fleet.core.types import FloatArray, Law, Posture
from fleet.core.wire import Obstacle

#: Integration step [s] and horizon [s] of the prediction rollouts.
PREDICTION_DT = 0.05
PREDICTION_HORIZON = 60.0
_DEFAULT_AVOIDANCE = Avoidance()


@dataclass(frozen=True)
class TaskSpec:
    """What the cost model needs of a task: goal, allowed laws and their gains."""

    goal: Posture
    laws: tuple[Law, ...]  # ("ccw", "cw") for auto
    gains: dict[Law, Gains]
    tolerance: Tolerance


def predicted_times(
    starts: Sequence[Posture],
    tasks: Sequence[TaskSpec],
    profile: RobotProfile | Sequence[RobotProfile],
    obstacles: Sequence[Obstacle] = (),
    avoidance: Avoidance = _DEFAULT_AVOIDANCE,
    dt: float = PREDICTION_DT,
    horizon: float = PREDICTION_HORIZON,
    nearest: int | None = None,
) -> FloatArray:
    """(R, T) matrix of predicted arrival times [s] (see the module docstring);
    ``profile``: every robot's, or one per robot (same order as ``starts``)."""
    n_r, n_t = len(starts), len(tasks)
    cost = np.full((n_r, n_t), np.inf)
    if n_r == 0 or n_t == 0:
        return cost
    profiles = [profile] * n_r if isinstance(profile, RobotProfile) else list(profile)
    speeds = np.array([p.max_speed for p in profiles], dtype=np.float64)
    top = np.where(np.isfinite(speeds), np.maximum(speeds, 1e-3), 1.0)  # (R,)
    top_speed = top[:, None]
    xy_r = np.array([s[:2] for s in starts], dtype=np.float64)
    xy_t = np.array([t.goal[:2] for t in tasks], dtype=np.float64)
    dist = np.hypot(xy_r[:, None, 0] - xy_t[None, :, 0], xy_r[:, None, 1] - xy_t[None, :, 1])
    priced = np.ones((n_r, n_t), dtype=bool)
    if nearest is not None and nearest < max(n_r, n_t):
        priced[:] = False
        k_r, k_t = min(nearest, n_r), min(nearest, n_t)
        by_task = np.argsort(dist, axis=0, kind="stable")[:k_r]  # nearest robots per task
        priced[by_task, np.arange(n_t)[None, :]] = True
        by_robot = np.argsort(dist, axis=1, kind="stable")[:, :k_t]  # nearest tasks per robot
        priced[np.arange(n_r)[:, None], by_robot] = True
        cost = np.where(priced, np.inf, horizon + dist / top_speed)
    rows: list[tuple[int, int, Law]] = [
        (i, j, law)
        for i in range(n_r)
        for j, task in enumerate(tasks)
        if priced[i, j]
        for law in task.laws
    ]
    start = np.array([starts[i] for i, _, _ in rows], dtype=np.float64)
    goal = np.array([tasks[j].goal for _, j, _ in rows], dtype=np.float64)
    problem = BatchProblem.build(
        start,
        goal,
        [tasks[j].gains[law] for _, j, law in rows],
        [law for _, _, law in rows],
        tolerance=[tasks[j].tolerance for _, j, _ in rows],
        profile=[profiles[i] for i, _, _ in rows],
        **obstacle_columns(obstacles),
        k_avoid=avoidance.k_avoid,
        min_x_oa=avoidance.min_x_oa,
        smoothing=avoidance.smoothing_m,
    )
    result = simulate(problem, dt=dt, max_time=horizon)
    remaining = np.hypot(result.final_pose[:, 0] - goal[:, 0], result.final_pose[:, 1] - goal[:, 1])
    row_speed = np.array([top[i] for i, _, _ in rows], dtype=np.float64)
    times = np.where(result.done, result.time, horizon + remaining / row_speed)
    for (i, j, _), t in zip(rows, times, strict=True):
        cost[i, j] = min(cost[i, j], float(t))
    return cost


def optimal_assignment(cost: FloatArray) -> list[tuple[int, int]]:
    """(robot index, task index) pairs minimising the total cost (Hungarian method).

    Rectangular matrices are fine: min(R, T) pairs are returned, sorted by task index.
    Infinite entries are treated as forbidden (never chosen if avoidable).
    """
    # scipy on first use: the fleet service plans with it, a robot (``robot`` extra) never.
    from scipy.optimize import linear_sum_assignment

    c = np.asarray(cost, dtype=np.float64)
    if c.size == 0:
        return []
    finite = np.isfinite(c)
    big = (np.abs(c[finite]).max() + 1.0) * (c.shape[0] + c.shape[1]) if finite.any() else 1.0
    rows, cols = linear_sum_assignment(np.where(finite, c, big))
    pairs = [(int(r), int(t)) for r, t in zip(rows, cols, strict=True) if finite[r, t]]
    return sorted(pairs, key=lambda p: p[1])
