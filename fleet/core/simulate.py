"""Batch closed-loop simulator: N unicycle robots under laws (17)/(20) at once.

Every step of every robot is the one compiled control step (:mod:`fleet.core.step`, the
code the robot agents run): forward Euler on the kinematics of Eq. (3) at ``dt`` (0.01 s in
the paper). Each robot has its own goal, gains, law, tolerance, wheel limits and body
radius; static obstacles and, optionally, the other robots act through the repulsion of
Eq. (27), and through the safety filter (``safety``; off by default, the paper's model).

Stop rule (DESIGN.md): a robot is done at the first step k whose *pre-step* error is within
tolerance (x_e^2 + y_e^2 < tol_position^2 and |theta_e| < tol_heading). That step is still
applied and counted, so its time is (k + 1) dt; afterwards the robot stands still (and
still acts on its peers).

Metrics per robot: control effort, Eq. (25), int(|u| + |omega|) dt; travelled distance
int |u| dt; time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
import numpy.typing as npt

from fleet.core.control import DEFAULT_MIN_X_OA, is_cw
from fleet.core.params import (
    DEFAULT_TOLERANCE,
    UNLIMITED,
    Gains,
    RobotProfile,
    SafetyConfig,
    Tolerance,
)
from fleet.core.route import route_table
from fleet.core.step import (
    DISTANCE,
    EFFORT,
    OBSTACLE_ROWS,
    PARALLEL_MIN_WORK,
    RECORD_COLUMNS,
    SAFETY_OFF,
    Interaction,
    Safety,
    Schedule,
    advance_batch,
    lower_min_separation,
    parallel_kernel,
    robot_params,
)
from fleet.core.types import BoolArray, FloatArray, IntArray, Law
from fleet.core.wire import DEFAULT_PASS_M, Obstacle

PAPER_DT = 0.01
#: Tolerance [s] on the end of a start delay (as ``robot_agent.logic.DELAY_EPS``).
DELAY_EPS = 1e-6
#: Recorded rows per compiled call when recording (bounds the buffers to rows x N x 8 floats).
RECORD_CHUNK_ROWS = 256


def batch_filter(config: SafetyConfig) -> Safety:
    """The safety filter the batch runs for robots configured with ``config``: every robot
    with :meth:`SafetyConfig.batch_spread` (the batch has no command latency or link)."""
    return Safety(*config.filter_terms(config.batch_spread()))


class ObstacleColumns(TypedDict):
    """The static-obstacle arguments of :meth:`BatchProblem.build`."""

    obstacles: list[tuple[float, float]]
    obstacle_radius: list[float]
    obstacle_body: list[float]
    obstacle_end: list[tuple[float, float]]


def obstacle_columns(obstacles: Sequence[Obstacle]) -> ObstacleColumns:
    """Posts and wall segments as :meth:`BatchProblem.build`'s obstacle arguments."""
    return ObstacleColumns(
        obstacles=[(o.x, o.y) for o in obstacles],
        obstacle_radius=[o.radius for o in obstacles],
        obstacle_body=[o.body_radius for o in obstacles],
        obstacle_end=[o.far_end for o in obstacles],
    )


def _column(values: npt.ArrayLike, n: int, name: str) -> FloatArray:
    arr = np.broadcast_to(np.asarray(values, dtype=np.float64), (n,)).copy()
    if np.isnan(arr).any():
        raise ValueError(f"{name} contains NaN")
    return arr


@dataclass(frozen=True)
class BatchProblem:
    """Everything the simulator needs, as arrays (one row per robot).

    Build it with :meth:`build`, which broadcasts scalars and pydantic models.
    """

    start: FloatArray  # (N, 3) world-frame postures [m, m, rad]
    goal: FloatArray  # (N, 3)
    gains: FloatArray  # (N, 3) = (kx, ky, ktheta)
    cw: BoolArray  # (N,) True -> law (20)
    tol_position: FloatArray  # (N,) [m]
    tol_heading: FloatArray  # (N,) [rad]
    wheel_radius: FloatArray  # (N,) [m]
    half_axle: FloatArray  # (N,) [m]
    max_wheel_speed: FloatArray  # (N,) [rad/s], inf = unlimited
    obstacles: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) [m]
    obstacle_radius: FloatArray = field(default_factory=lambda: np.zeros(0))  # (M,) [m]
    #: (M,) body radius [m] of each obstacle (the safety filter's); None: 0 m (a point).
    obstacle_body: FloatArray | None = None
    #: (M, 2) [m] the far end of each obstacle's segment (a wall from ``obstacles`` to it);
    #: None: every obstacle is a post.
    obstacle_end: FloatArray | None = None
    k_avoid: float = 0.0  # K_avoid of Eq. (27) [m^2/s]
    peer_radius: float = 0.0  # influence radius of each robot on its peers [m]; 0 = off
    min_x_oa: float = DEFAULT_MIN_X_OA
    #: [m] width of Eq. (27)'s smoothed bands, every robot's (0: the paper's term).
    smoothing: float = 0.0
    #: (N,) [s] each robot stands still (u = omega = 0) while t < start_delay - DELAY_EPS,
    #: like an agent in its start delay; arrival is checked throughout. None: no delays.
    start_delay: FloatArray | None = None
    #: (N,) body radius [m] of each robot (the safety filter's); None: 0 m.
    body_radius: FloatArray | None = None
    #: The safety filter (:class:`fleet.core.step.Safety`); off: the paper's model.
    safety: Safety = SAFETY_OFF
    #: (``ROUTE_ROWS``, M) every robot's route table (its via-points, then its goal;
    #: :mod:`fleet.core.step`), robot i's in columns ``route_first[i] .. route_last[i]``
    #: (-1: no route, the robot aims at its goal). None: no robot has a route.
    route: FloatArray | None = None
    route_first: IntArray | None = None
    route_last: IntArray | None = None
    #: (N,) [m] pass-through radius of each robot's via-points.
    pass_radius: FloatArray | None = None

    @property
    def size(self) -> int:
        return int(self.start.shape[0])

    def params(self) -> FloatArray:
        """Parameter rows of :mod:`fleet.core.step` (N, ``ROBOT_COLUMNS``) (a robot with a
        route aims along it at every step: :func:`fleet.core.step.aim`)."""
        n = self.size
        return robot_params(
            self.goal,
            self.gains,
            self.cw.astype(np.float64),
            self.tol_position,
            self.tol_heading,
            self.wheel_radius,
            self.half_axle,
            self.max_wheel_speed,
            np.zeros(n) if self.body_radius is None else self.body_radius,
            None if self.start_delay is None else self.start_delay - DELAY_EPS,
            None if self.route_last is None else self.route_last.astype(np.float64),
            0.0 if self.pass_radius is None else self.pass_radius,
            self.smoothing,
        )

    def legs(self) -> IntArray:
        """(N,) the route entry each robot aims at first (-1: no route)."""
        if self.route_first is None:
            return np.full(self.size, -1, dtype=np.int64)
        return self.route_first.astype(np.int64)

    @classmethod
    def build(
        cls,
        start: npt.ArrayLike,
        goal: npt.ArrayLike,
        gains: Gains | Sequence[Gains] | npt.ArrayLike,
        law: Law | Sequence[Law] | npt.ArrayLike,
        tolerance: Tolerance | Sequence[Tolerance] = DEFAULT_TOLERANCE,
        profile: RobotProfile | Sequence[RobotProfile] = UNLIMITED,
        obstacles: npt.ArrayLike = (),
        obstacle_radius: npt.ArrayLike = 1.0,
        k_avoid: float = 0.0,
        peer_radius: float = 0.0,
        min_x_oa: float = DEFAULT_MIN_X_OA,
        start_delay: npt.ArrayLike | None = None,
        obstacle_body: npt.ArrayLike = 0.0,
        safety: Safety = SAFETY_OFF,
        obstacle_end: npt.ArrayLike | None = None,
        routes: Sequence[npt.ArrayLike | None] | None = None,
        pass_radius: npt.ArrayLike = DEFAULT_PASS_M,
        smoothing: float = 0.0,
    ) -> BatchProblem:
        """Broadcast per-robot inputs (scalars, models or arrays) to an N-robot problem.

        ``routes[i]``: robot i's via-points (m_i, 2) [m], world frame, its goal left out
        (:mod:`fleet.core.route`); None or no rows: straight to the goal.
        ``pass_radius`` [m]: the via-points' pass-through radius, at least the position
        tolerance. ``smoothing`` [m]: Eq. (27)'s smoothed bands (``Avoidance.smoothing_m``).
        """
        start_arr = np.atleast_2d(np.asarray(start, dtype=np.float64))
        n = start_arr.shape[0]
        goal_arr = np.broadcast_to(np.atleast_2d(np.asarray(goal, dtype=np.float64)), (n, 3))
        if start_arr.shape != (n, 3):
            raise ValueError(f"start must have shape (N, 3), got {start_arr.shape}")
        if not (np.isfinite(start_arr).all() and np.isfinite(goal_arr).all()):
            raise ValueError("start and goal postures must be finite")

        if isinstance(gains, Gains):
            gains_arr = np.array(gains.as_tuple())
        elif isinstance(gains, Sequence) and gains and isinstance(gains[0], Gains):
            gains_arr = np.array([g.as_tuple() for g in gains if isinstance(g, Gains)])
        else:
            gains_arr = np.asarray(gains, dtype=np.float64)
        gains_arr = np.broadcast_to(gains_arr, (n, 3)).copy()
        if not (gains_arr > 0).all():
            raise ValueError("gains must be strictly positive")

        tols = tolerance if isinstance(tolerance, Sequence) else [tolerance] * n
        profs = profile if isinstance(profile, Sequence) else [profile] * n
        obs = np.asarray(obstacles, dtype=np.float64).reshape(-1, 2)
        ends = None if obstacle_end is None else np.asarray(obstacle_end, np.float64).reshape(-1, 2)
        if ends is not None and ends.shape != obs.shape:
            raise ValueError(f"obstacle_end must have shape {obs.shape}, got {ends.shape}")
        law_cw = np.broadcast_to(is_cw(law), (n,)).copy()
        tol_position = _column([t.position for t in tols], n, "tol_position")
        passing = _column(pass_radius, n, "pass_radius")
        table = _route_table(routes, goal_arr, law_cw, n)
        if table is not None and (passing < tol_position).any():
            raise ValueError("pass_radius must be at least the position tolerance")
        return cls(
            start=start_arr.copy(),
            goal=goal_arr.copy(),
            gains=gains_arr,
            cw=law_cw,
            tol_position=tol_position,
            tol_heading=_column([t.heading for t in tols], n, "tol_heading"),
            wheel_radius=_column([p.wheel_radius for p in profs], n, "wheel_radius"),
            half_axle=_column([p.half_axle for p in profs], n, "half_axle"),
            max_wheel_speed=_column([p.max_wheel_speed for p in profs], n, "max_wheel_speed"),
            obstacles=obs,
            obstacle_radius=_column(obstacle_radius, obs.shape[0], "obstacle_radius"),
            obstacle_body=_column(obstacle_body, obs.shape[0], "obstacle_body"),
            obstacle_end=ends,
            k_avoid=float(k_avoid),
            peer_radius=float(peer_radius),
            min_x_oa=float(min_x_oa),
            smoothing=float(smoothing),
            start_delay=None if start_delay is None else _column(start_delay, n, "start_delay"),
            body_radius=_column([p.radius for p in profs], n, "body_radius"),
            safety=safety,
            route=None if table is None else table[0],
            route_first=None if table is None else table[1],
            route_last=None if table is None else table[2],
            pass_radius=passing,
        )


def _route_table(
    routes: Sequence[npt.ArrayLike | None] | None, goal: FloatArray, cw: BoolArray, n: int
) -> tuple[FloatArray, IntArray, IntArray] | None:
    """The batch's route table and each robot's first and last column (-1: no route), or
    None when no robot has a via-point."""
    if routes is None:
        return None
    if len(routes) != n:
        raise ValueError(f"routes must have one entry per robot ({n}), got {len(routes)}")
    columns: list[FloatArray] = []
    first = np.full(n, -1, dtype=np.int64)
    last = np.full(n, -1, dtype=np.int64)
    used = 0
    for i, via in enumerate(routes):
        rows = np.zeros((0, 2)) if via is None else np.asarray(via, dtype=np.float64)
        rows = rows.reshape(-1, 2)
        if rows.shape[0] == 0:
            continue
        if not np.isfinite(rows).all():
            raise ValueError(f"route {i} must be finite")
        table = route_table(rows, (goal[i, 0], goal[i, 1], goal[i, 2]), bool(cw[i]))
        columns.append(table)
        first[i], last[i] = used, used + table.shape[1] - 1
        used += table.shape[1]
    if not columns:
        return None
    return np.ascontiguousarray(np.hstack(columns)), first, last


@dataclass(frozen=True)
class Trajectory:
    """Recorded signals: ``poses`` (T+1, N, 3); ``controls`` (T, N, 2) = (u, omega);
    ``errors`` (T, N, 3) = pre-step (x_e, y_e, theta_e). Row k of controls/errors is step k."""

    poses: FloatArray
    controls: FloatArray
    errors: FloatArray

    def wheel_speeds(self, wheel_radius: float, half_axle: float) -> tuple[FloatArray, FloatArray]:
        """Right/left wheel speeds [rad/s] of the recorded controls, Eq. (2)."""
        from fleet.core.control import wheel_speeds

        return wheel_speeds(self.controls[..., 0], self.controls[..., 1], wheel_radius, half_axle)


@dataclass(frozen=True)
class SimResult:
    """Outcome of :func:`simulate`, one entry per robot."""

    done: BoolArray  # reached tolerance
    time: FloatArray  # [s]; NaN where not done
    control_effort: FloatArray  # Eq. (25)
    distance: FloatArray  # int |u| dt [m]
    final_pose: FloatArray  # (N, 3)
    steps: int  # steps simulated for the whole batch
    min_pair_distance: FloatArray | None = None  # (N, N) min centre distance over time [m]
    trajectory: Trajectory | None = None
    #: (N,) how many of its via-points each robot passed (None: no robot had a route); a
    #: run continued from ``final_pose`` goes on with the rest of each route
    passed: IntArray | None = None

    @property
    def min_separation(self) -> float:
        """Smallest centre distance between any two robots over the run [m] (inf if N < 2)."""
        if self.min_pair_distance is None or self.min_pair_distance.shape[0] < 2:
            return float("inf")
        return float(self.min_pair_distance.min())


def _recorded_steps(start: int, end: int, every: int) -> int:
    """How many steps k in [start, end) have k % every == 0."""
    return -(-end // every) - -(-start // every)


def simulate(
    problem: BatchProblem,
    dt: float = PAPER_DT,
    max_time: float = 60.0,
    record: bool = False,
    track_separation: bool = False,
    group: int = 0,
    record_every: int = 1,
    parallel: bool | None = None,
) -> SimResult:
    """Simulate the closed-loop batch until every robot is done or ``max_time`` [s] passes.

    Every step of every robot is :func:`fleet.core.step.robot_step`, run compiled by
    :func:`fleet.core.step.advance_batch` (many steps per call, on both cores for large
    batches). ``record`` keeps poses, controls and errors of every ``record_every``-th step
    (memory T/record_every x N; the final pose is always kept); ``track_separation``
    keeps the minimum centre distance of every pair over the run (cost N^2 per step).
    ``group`` > 0 splits the batch into independent consecutive blocks of ``group`` rows
    (e.g. copies of one scene): peers repel, guard against contact and are tracked only
    within a block (cost N x group per step instead of N^2); pairs across blocks get an
    infinite ``min_pair_distance``. Static obstacles still act on every row. ``parallel``:
    whether large batches take the parallel kernel (``advance_batch``; None: as this
    process does, building it at the first or, deferred, once built).
    """
    if dt <= 0 or not np.isfinite(dt):
        raise ValueError("dt must be a positive finite number of seconds")
    if record_every < 1:
        raise ValueError("record_every must be at least 1")
    n = problem.size
    if group < 0 or (group > 0 and n % group != 0):
        raise ValueError("group must divide the batch size")
    g = group if group > 0 else max(n, 1)
    blocks = n // g
    pose = np.array(problem.start.T, order="C")  # a copy: the problem stays as built
    params = problem.params()
    route = problem.route
    leg = problem.legs()
    done_step = np.full(n, -1, dtype=np.int64)
    metrics = np.zeros((2, n))
    obstacles = np.zeros((OBSTACLE_ROWS, 0))
    filtered = problem.safety.margin >= 0.0
    routed = problem.route is not None  # routes look past their corners at the bodies
    if (problem.k_avoid > 0 or filtered or routed) and problem.obstacles.shape[0] > 0:
        m = problem.obstacles.shape[0]
        body = np.zeros(m) if problem.obstacle_body is None else problem.obstacle_body
        influence = problem.obstacle_radius if problem.k_avoid > 0 else np.zeros(m)
        end = problem.obstacles if problem.obstacle_end is None else problem.obstacle_end
        obstacles = np.ascontiguousarray(
            np.vstack([problem.obstacles.T, influence[None, :], body[None, :], end.T])
        )
    interaction = Interaction(
        g, problem.k_avoid, problem.peer_radius, problem.min_x_oa, problem.safety
    )
    min_pair_sq = np.full((blocks, g, g), np.inf) if track_separation else None
    recorded: list[FloatArray] = []

    max_steps = round(max_time / dt)
    # Without recording, one call runs to the end; recording goes in chunks of bounded memory.
    span = RECORD_CHUNK_ROWS * record_every if record else max_steps
    step = 0
    while step < max_steps and (done_step < 0).any():
        steps = min(span, max_steps - step)
        buffer = None
        if record:
            rows = _recorded_steps(step, step + steps, record_every)
            buffer = np.empty((rows, n, RECORD_COLUMNS))
        taken = advance_batch(
            pose, params, done_step, metrics, obstacles, interaction,
            Schedule(dt, step, steps, record_every), buffer, min_pair_sq, route, leg, parallel,
        )  # fmt: skip
        if buffer is not None:  # rows after the last robot was done are not part of the run
            recorded.append(buffer[: _recorded_steps(step, step + taken, record_every)])
        step += taken
        if taken < steps:
            break

    min_pair_full = None
    if min_pair_sq is not None:
        lower_min_separation(pose, g, min_pair_sq, 0, blocks)
        min_pair = np.sqrt(min_pair_sq)
        min_pair_full = np.full((n, n), np.inf)
        for b in range(blocks):
            min_pair_full[b * g : (b + 1) * g, b * g : (b + 1) * g] = min_pair[b]
        np.fill_diagonal(min_pair_full, np.inf)
    done = done_step >= 0
    final_pose = np.ascontiguousarray(pose.T)
    trajectory = None
    if record:
        steps_recorded = np.concatenate([*recorded, np.zeros((0, n, RECORD_COLUMNS))])
        trajectory = Trajectory(
            poses=np.concatenate([steps_recorded[..., 0:3], final_pose[None]]),
            controls=steps_recorded[..., 3:5],
            errors=steps_recorded[..., 5:8],
        )
    return SimResult(
        done=done,
        time=np.where(done, (done_step + 1) * dt, np.nan),
        control_effort=metrics[EFFORT],
        distance=metrics[DISTANCE],
        final_pose=final_pose,
        steps=step,
        min_pair_distance=min_pair_full,
        trajectory=trajectory,
        passed=None if problem.route is None else np.where(leg >= 0, leg - problem.legs(), 0),
    )


def warm_parallel_kernel() -> str:
    """Build the kernel that spreads large batches over the threads now, compiling it or
    loading it from numba's cache (:func:`fleet.core.step.parallel_kernel`): one step of a
    batch just large enough to take that path. About a minute on a fresh install, once
    (later processes load it from the cache); a process that defers it
    (:func:`fleet.core.step.defer_parallel_kernel`) calls this on a thread of its own.
    Returns the kernel's state ("ready", or why it is unusable)."""
    n = PARALLEL_MIN_WORK + 1
    spots = np.zeros((n, 3))
    spots[:, 0] = np.arange(n, dtype=np.float64)
    problem = BatchProblem.build(spots, spots, Gains(kx=1.0, ky=1.0, ktheta=1.0), "ccw")
    simulate(problem, dt=0.02, max_time=0.02, parallel=True)
    return parallel_kernel()
