"""Batch closed-loop simulator: N unicycle robots under laws (17)/(20) at once.

Forward Euler on the kinematics of Eq. (3) at ``dt`` (0.01 s in the paper). Each robot
has its own goal, gains, law, tolerance and wheel limits; static obstacles and, optionally,
the other robots act through the repulsion of Eq. (27).

Stop rule (DESIGN.md): a robot is done at the first step k whose *pre-step* error is within
tolerance (||(x_e, y_e)|| < tol_position and |theta_e| < tol_heading). That step is still
applied and counted, so its time is (k + 1) dt; afterwards the robot stands still.

Metrics per robot: control effort, Eq. (25), int(|u| + |omega|) dt; travelled distance
int |u| dt; time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from fleet.core.control import DEFAULT_MIN_X_OA, TWO_PI, is_cw, obstacle_repulsion
from fleet.core.params import DEFAULT_TOLERANCE, UNLIMITED, Gains, RobotProfile, Tolerance
from fleet.core.types import BoolArray, FloatArray, Law

PAPER_DT = 0.01
#: Tolerance [s] on the end of a start delay (as ``robot_agent.logic.DELAY_EPS``).
DELAY_EPS = 1e-6


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
    k_avoid: float = 0.0  # K_avoid of Eq. (27) [m^2/s]
    peer_radius: float = 0.0  # influence radius of each robot on its peers [m]; 0 = off
    min_x_oa: float = DEFAULT_MIN_X_OA
    #: (N,) [s] each robot stands still (u = omega = 0) while t < start_delay - DELAY_EPS,
    #: like an agent in its start delay; arrival is checked throughout. None: no delays.
    start_delay: FloatArray | None = None

    @property
    def size(self) -> int:
        return int(self.start.shape[0])

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
    ) -> BatchProblem:
        """Broadcast per-robot inputs (scalars, models or arrays) to an N-robot problem."""
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
        return cls(
            start=start_arr.copy(),
            goal=goal_arr.copy(),
            gains=gains_arr,
            cw=np.broadcast_to(is_cw(law), (n,)).copy(),
            tol_position=_column([t.position for t in tols], n, "tol_position"),
            tol_heading=_column([t.heading for t in tols], n, "tol_heading"),
            wheel_radius=_column([p.wheel_radius for p in profs], n, "wheel_radius"),
            half_axle=_column([p.half_axle for p in profs], n, "half_axle"),
            max_wheel_speed=_column([p.max_wheel_speed for p in profs], n, "max_wheel_speed"),
            obstacles=obs,
            obstacle_radius=_column(obstacle_radius, obs.shape[0], "obstacle_radius"),
            k_avoid=float(k_avoid),
            peer_radius=float(peer_radius),
            min_x_oa=float(min_x_oa),
            start_delay=None if start_delay is None else _column(start_delay, n, "start_delay"),
        )


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

    @property
    def min_separation(self) -> float:
        """Smallest centre distance between any two robots over the run [m] (inf if N < 2)."""
        if self.min_pair_distance is None or self.min_pair_distance.shape[0] < 2:
            return float("inf")
        return float(self.min_pair_distance.min())


class _Workspace:
    """Preallocated per-step buffers so the hot loop allocates little."""

    def __init__(self, n: int) -> None:
        self.c = np.empty(n)
        self.s = np.empty(n)
        self.dx = np.empty(n)
        self.dy = np.empty(n)
        self.tmp = np.empty(n)
        self.x_e = np.empty(n)
        self.y_e = np.empty(n)
        self.theta_e = np.empty(n)
        self.y_e_sq = np.empty(n)
        self.abs_theta_e = np.empty(n)
        self.mag = np.empty(n)
        self.u = np.empty(n)
        self.omega = np.empty(n)
        self.abs_u = np.empty(n)
        self.inside = np.empty(n, dtype=bool)
        self.mask = np.empty(n, dtype=bool)


def _wrap_heading_into(theta: FloatArray, ws: _Workspace) -> None:
    """(11.a): ``theta`` mapped to [0, 2pi) into ``ws.tmp``, bit for bit ``wrap_to_2pi``.

    ``np.mod`` costs as much as a sine, so the remainder is formed directly for
    theta in [-4pi, 6pi) (robots turn a few times at most): with k = floor(theta / 2pi)
    clipped to [-2, 2], k 2pi is exact and theta - k 2pi is exact for k >= 0 (Sterbenz)
    and, for k < 0, the single rounding that numpy's remainder also makes (exact ``fmod``,
    then one addition of 2pi). A k misjudged by the rounded division lands outside
    [0, 2pi], as does any other angle or NaN: those entries take ``np.mod``.
    """
    np.divide(theta, TWO_PI, out=ws.tmp)
    np.floor(ws.tmp, out=ws.tmp)
    np.clip(ws.tmp, -2.0, 2.0, out=ws.tmp)
    ws.tmp *= TWO_PI
    np.subtract(theta, ws.tmp, out=ws.tmp)
    low, high = ws.tmp.min(), ws.tmp.max()
    if not (low >= 0.0 and high <= TWO_PI):
        np.greater_equal(ws.tmp, 0.0, out=ws.mask)  # False for NaN
        np.logical_not(ws.mask, out=ws.mask)
        ws.mask |= ws.tmp > TWO_PI
        ws.tmp[ws.mask] = np.mod(theta[ws.mask], TWO_PI)
        high = ws.tmp.max()
    if not high < TWO_PI:  # np.mod can round a tiny negative angle up to exactly 2pi
        np.greater_equal(ws.tmp, TWO_PI, out=ws.mask)
        ws.tmp[ws.mask] = 0.0


def _pose_error_into(
    x: FloatArray,
    y: FloatArray,
    theta: FloatArray,
    goal_x: FloatArray,
    goal_y: FloatArray,
    goal_theta_wrapped: FloatArray,
    cw: BoolArray,
    ws: _Workspace,
) -> None:
    """Eq. (5) with the wraps (11.a)/(11.b)/(21), written into ``ws.x_e/y_e/theta_e``.

    Same arithmetic as :func:`fleet.core.control.pose_error`; property tests hold them equal.
    Conditional +-2pi shifts are done as ``+= mask * 2pi`` (adding 0.0 is exact), which is
    several times cheaper than ufuncs with ``where=``; the rare rounding guards run only
    when a reduction shows they are needed.
    """
    np.cos(theta, out=ws.c)
    np.sin(theta, out=ws.s)
    np.subtract(goal_x, x, out=ws.dx)
    np.subtract(goal_y, y, out=ws.dy)
    np.multiply(ws.c, ws.dx, out=ws.x_e)
    np.multiply(ws.s, ws.dy, out=ws.tmp)
    ws.x_e += ws.tmp
    np.multiply(ws.c, ws.dy, out=ws.y_e)
    np.multiply(ws.s, ws.dx, out=ws.tmp)
    ws.y_e -= ws.tmp
    # (11.a) on the robot heading; the goal heading was wrapped once up front.
    _wrap_heading_into(theta, ws)
    te = ws.theta_e
    np.subtract(goal_theta_wrapped, ws.tmp, out=te)
    np.less(te, 0.0, out=ws.mask)
    np.multiply(ws.mask, TWO_PI, out=ws.tmp)
    te += ws.tmp  # (11.b)
    if te.max() >= TWO_PI:  # -1e-300 + 2pi rounds to 2pi: that error is really zero
        np.greater_equal(te, TWO_PI, out=ws.mask)
        te[ws.mask] = 0.0
    np.greater(te, 0.0, out=ws.mask)
    ws.mask &= cw
    np.multiply(ws.mask, TWO_PI, out=ws.tmp)
    te -= ws.tmp  # (21)
    if te.min() <= -TWO_PI:
        np.less_equal(te, -TWO_PI, out=ws.mask)
        te[ws.mask] = 0.0


def _law_into(
    kx: FloatArray, signed_ky: FloatArray, signed_ktheta: FloatArray, ws: _Workspace
) -> None:
    """Laws (17)/(20) into ``ws.u``/``ws.omega``; same arithmetic as ``posture_law``.

    Expects ``ws.y_e_sq`` = y_e^2 and ``ws.abs_theta_e`` = |theta_e| (shared with the stop
    rule). ``signed_ky``/``signed_ktheta`` carry the law's sign (negative for cw): rounding
    is symmetric, so (-a)(b) + (-c)(d) is bit for bit -(ab + cd).
    """
    np.multiply(kx, ws.x_e, out=ws.u)
    np.multiply(ws.y_e_sq, signed_ky, out=ws.mag)
    np.multiply(ws.theta_e, ws.theta_e, out=ws.tmp)
    ws.tmp *= signed_ktheta
    ws.mag += ws.tmp
    np.negative(ws.abs_theta_e, out=ws.tmp)
    np.exp(ws.tmp, out=ws.tmp)
    np.multiply(ws.mag, ws.tmp, out=ws.omega)


def _saturate_into(
    wheel_radius: FloatArray, half_axle: FloatArray, max_wheel_speed: FloatArray, ws: _Workspace
) -> None:
    """``control.saturate`` in place on ``ws.u``/``ws.omega`` (bit for bit; x * 1.0 == x)."""
    right, left, peak = ws.dx, ws.dy, ws.tmp
    np.multiply(half_axle, ws.omega, out=peak)
    np.add(ws.u, peak, out=right)
    right /= wheel_radius
    np.subtract(ws.u, peak, out=left)
    left /= wheel_radius
    np.abs(right, out=right)
    np.abs(left, out=left)
    np.maximum(right, left, out=peak)
    np.greater(peak, max_wheel_speed, out=ws.mask)
    if not ws.mask.any():
        return
    np.maximum(peak, 1e-300, out=peak)
    np.divide(max_wheel_speed, peak, out=peak)
    np.logical_not(ws.mask, out=ws.mask)
    peak[ws.mask] = 1.0
    ws.u *= peak
    ws.omega *= peak


def simulate(
    problem: BatchProblem,
    dt: float = PAPER_DT,
    max_time: float = 60.0,
    record: bool = False,
    track_separation: bool = False,
    group: int = 0,
    record_every: int = 1,
) -> SimResult:
    """Simulate the closed-loop batch until every robot is done or ``max_time`` [s] passes.

    ``record`` keeps poses, controls and errors of every ``record_every``-th step (memory
    T/record_every x N; the final pose is always kept); ``track_separation``
    keeps the minimum centre distance of every pair over the run (cost N^2 per step).
    ``group`` > 0 splits the batch into independent consecutive blocks of ``group`` rows
    (e.g. copies of one scene): peers repel, and separations are tracked, only within a
    block (cost N x group per step instead of N^2); pairs across blocks get an infinite
    ``min_pair_distance``. Static obstacles still act on every row.
    """
    if dt <= 0 or not np.isfinite(dt):
        raise ValueError("dt must be a positive finite number of seconds")
    if record_every < 1:
        raise ValueError("record_every must be at least 1")
    n = problem.size
    if group < 0 or (group > 0 and n % group != 0):
        raise ValueError("group must divide the batch size")
    g = group if group > 0 else n
    blocks = n // g if g > 0 else 0
    x = problem.start[:, 0].copy()
    y = problem.start[:, 1].copy()
    theta = problem.start[:, 2].copy()
    goal = problem.goal
    goal_x = np.ascontiguousarray(goal[:, 0])
    goal_y = np.ascontiguousarray(goal[:, 1])
    goal_theta_wrapped = np.mod(goal[:, 2], TWO_PI)
    goal_theta_wrapped[goal_theta_wrapped >= TWO_PI] = 0.0
    cw = problem.cw
    # Contiguous gain columns; the law's sign folded into the omega gains (see _law_into).
    law_sign = np.where(cw, -1.0, 1.0)
    kx = np.ascontiguousarray(problem.gains[:, 0])
    signed_ky = problem.gains[:, 1] * law_sign
    signed_ktheta = problem.gains[:, 2] * law_sign
    tol_pos_sq = problem.tol_position**2
    limited = bool(np.isfinite(problem.max_wheel_speed).any())
    has_obstacles = problem.k_avoid > 0 and problem.obstacles.shape[0] > 0
    peers = problem.k_avoid > 0 and problem.peer_radius > 0 and n > 1
    delay_end = None
    if problem.start_delay is not None and bool((problem.start_delay > 0).any()):
        delay_end = problem.start_delay - DELAY_EPS
    waiting = np.empty(n, dtype=bool)

    ws = _Workspace(n)
    active = np.ones(n, dtype=bool)
    all_active = n > 0
    finished_now = np.empty(n, dtype=bool)
    done_step = np.full(n, -1, dtype=np.int64)
    effort = np.zeros(n)
    distance = np.zeros(n)
    peer_radius = np.zeros((0, 0))
    if peers:  # (N, group): only when peers repel, never for large batches without them
        peer_radius = np.full((blocks, g, g), problem.peer_radius)
        peer_radius[:, np.arange(g), np.arange(g)] = 0.0
        peer_radius = peer_radius.reshape(n, g)
    min_pair = np.full((blocks, g, g), np.inf) if track_separation else None
    poses: list[FloatArray] = []
    controls: list[FloatArray] = []
    errors: list[FloatArray] = []

    max_steps = round(max_time / dt)
    step = 0
    while step < max_steps and (all_active or active.any()):
        if min_pair is not None:
            xb, yb = x.reshape(blocks, g), y.reshape(blocks, g)
            d = np.hypot(xb[:, :, None] - xb[:, None, :], yb[:, :, None] - yb[:, None, :])
            np.minimum(min_pair, d, out=min_pair)
        _pose_error_into(x, y, theta, goal_x, goal_y, goal_theta_wrapped, cw, ws)
        # Stop rule: pre-step error inside tolerance -> done at this step (still applied).
        np.multiply(ws.y_e, ws.y_e, out=ws.y_e_sq)
        np.multiply(ws.x_e, ws.x_e, out=ws.tmp)
        ws.tmp += ws.y_e_sq
        np.less(ws.tmp, tol_pos_sq, out=finished_now)
        np.abs(ws.theta_e, out=ws.abs_theta_e)
        np.less(ws.abs_theta_e, problem.tol_heading, out=ws.inside)
        finished_now &= ws.inside
        finished_now &= active
        any_finished = bool(finished_now.any())
        if any_finished:
            done_step[finished_now] = step

        _law_into(kx, signed_ky, signed_ktheta, ws)
        if has_obstacles or peers:
            pose = np.stack([x, y, theta], axis=1)
            if has_obstacles:
                ws.u += obstacle_repulsion(
                    pose,
                    problem.obstacles,
                    problem.obstacle_radius,
                    problem.k_avoid,
                    problem.min_x_oa,
                )
            if peers:
                xy = np.stack([x, y], axis=1).reshape(blocks, 1, g, 2)
                positions = np.broadcast_to(xy, (blocks, g, g, 2)).reshape(n, g, 2)
                ws.u += obstacle_repulsion(
                    pose, positions, peer_radius, problem.k_avoid, problem.min_x_oa
                )
        if limited:
            _saturate_into(problem.wheel_radius, problem.half_axle, problem.max_wheel_speed, ws)
        if not all_active:
            np.logical_not(active, out=ws.mask)
            ws.u[ws.mask] = 0.0
            ws.omega[ws.mask] = 0.0
        if delay_end is not None:  # robots in their start delay stand still
            np.less(step * dt, delay_end, out=waiting)
            if waiting.any():
                ws.u[waiting] = 0.0
                ws.omega[waiting] = 0.0
            else:
                delay_end = None

        if record and step % record_every == 0:
            poses.append(np.stack([x, y, theta], axis=1))
            controls.append(np.stack([ws.u, ws.omega], axis=1))
            errors.append(np.stack([ws.x_e, ws.y_e, ws.theta_e], axis=1))

        # Metrics: Eq. (25) effort int(|u| + |omega|) dt, distance int |u| dt.
        np.abs(ws.u, out=ws.abs_u)
        np.abs(ws.omega, out=ws.tmp)
        ws.tmp += ws.abs_u
        ws.tmp *= dt
        effort += ws.tmp
        ws.abs_u *= dt
        distance += ws.abs_u
        # Forward Euler on Eq. (3).
        ws.c *= ws.u
        ws.c *= dt
        x += ws.c
        ws.s *= ws.u
        ws.s *= dt
        y += ws.s
        ws.omega *= dt
        theta += ws.omega

        if any_finished:
            active &= ~finished_now
            all_active = False
        step += 1

    min_pair_full = None
    if min_pair is not None:
        xb, yb = x.reshape(blocks, g), y.reshape(blocks, g)
        d = np.hypot(xb[:, :, None] - xb[:, None, :], yb[:, :, None] - yb[:, None, :])
        np.minimum(min_pair, d, out=min_pair)
        if blocks == 1:
            min_pair_full = min_pair.reshape(n, n)
        else:
            min_pair_full = np.full((n, n), np.inf)
            for b in range(blocks):
                min_pair_full[b * g : (b + 1) * g, b * g : (b + 1) * g] = min_pair[b]
        np.fill_diagonal(min_pair_full, np.inf)
    done = done_step >= 0
    trajectory = None
    if record:
        poses.append(np.stack([x, y, theta], axis=1))
        trajectory = Trajectory(
            poses=np.asarray(poses),
            controls=np.asarray(controls).reshape(-1, n, 2),
            errors=np.asarray(errors).reshape(-1, n, 3),
        )
    return SimResult(
        done=done,
        time=np.where(done, (done_step + 1) * dt, np.nan),
        control_effort=effort,
        distance=distance,
        final_pose=np.stack([x, y, theta], axis=1),
        steps=step,
        min_pair_distance=min_pair_full,
        trajectory=trajectory,
    )
