"""THE closed-loop control step, compiled with numba: one robot, one forward-Euler step.

Every robot motion in parkfleet goes through this module: the robot agent (one robot per
control tick, :func:`step_robot`), the simulated drive (:func:`integrate_wheels`), and the
batch simulator -- hence the planner's rollouts -- (:func:`advance_batch`: N robots, many
steps per call). :mod:`fleet.core.reference` writes the same maths in plain Python as the
tests' oracle only.

One step of one robot (:func:`robot_step`), in this order:

1. posture error p_e = (x_e, y_e, theta_e): the goal in the robot frame, Eq. (5), with the
   heading wrapped by (11.a) and then (11.b) for ``ccw`` or (21) for ``cw``;
2. stop rule: the robot is *done* when the pre-step error is within tolerance,
   x_e^2 + y_e^2 < tol_position^2 and |theta_e| < tol_heading; the step is still applied
   (its time is (k + 1) dt) and the caller stops the robot after it;
3. a held robot (start delay, ``hold``) stands still: u = omega = 0;
4. law (17) (``ccw``) or (20) (``cw``): u = kx x_e, omega = +-(ky y_e^2 + ktheta theta_e^2)
   e^-|theta_e|;
5. Eq. (27): -K_avoid / x_OA added to u for every peer closer than ``peer_radius`` and every
   static obstacle closer than its own radius; x_OA (Eq. 26, the obstacle's coordinate
   along the heading) is floored at ``min_x_oa`` keeping its sign (0 counts as ahead);
6. saturation: u and omega divided by the same factor so that neither wheel of Eq. (2)
   exceeds ``max_wheel_speed`` (the curvature omega/u is kept);
7. contact guard: u = 0 when it would move the robot towards a peer closer than
   2 body radius + min_x_oa (forwards to one ahead, backwards to one behind); turning on
   the spot stays allowed (Eq. 27 alone can let a robot settle in contact with a peer);
8. forward Euler on Eq. (3) with the pre-step heading: x += cos(theta) u dt, ...

Steps 5 and 7 are on only when K_avoid > 0.

**Numerics.** IEEE double arithmetic in a fixed order with libm's ``sin``, ``cos`` and ``exp``
(the functions Python's :mod:`math` calls), no fastmath and no fused multiply-add, so a step
equals the plain-Python reference bit for bit when both sum in the same order. The wrap
(11.a) forms the exact remainder theta - k 2pi directly (see :func:`wrap_to_2pi`).

**Data.** A robot is a row of ``params`` (columns ``GOAL_X`` ... ``DELAY_END``, built by
:func:`robot_params`); positions are rows: ``positions[0]`` = x, ``positions[1]`` = y [m];
static obstacles are ``obstacles[0]`` = x, ``obstacles[1]`` = y, ``obstacles[2]`` = influence
radius [m].

**Compilation.** Every function is compiled with ``cache=True`` (machine code kept in this
package's ``__pycache__``, or numba's per-user cache directory when that is read-only).
The entry points of the agent and the drive carry explicit signatures: they are compiled,
or loaded from the cache, when this module is imported -- never inside a control tick --
and a call with other types raises instead of compiling. The batch kernel compiles at a
process's first batch simulation. All compiled code lives in this one file on purpose:
numba's cache is invalidated by a change of the file a function was compiled from, not by
changes in the files it calls into.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numba
import numpy as np
import numpy.typing as npt
from numba import njit, prange

from fleet.core.types import FloatArray

TWO_PI = 2.0 * math.pi

# Columns of a robot's parameter row (``params[i]``).
GOAL_X = 0  # goal posture, world frame [m]
GOAL_Y = 1
GOAL_HEADING = 2  # [rad], wrapped to [0, 2pi) by (11.a) (robot_params does it)
CW = 3  # 1.0: clockwise law (20); 0.0: counter-clockwise law (17)
KX = 4  # gains of laws (17)/(20)
KY = 5
KTHETA = 6
TOL_POSITION_SQ = 7  # squared position tolerance [m^2]
TOL_HEADING = 8  # heading tolerance [rad]
WHEEL_RADIUS = 9  # r of Eq. (2) [m]
HALF_AXLE = 10  # b of Eq. (2) [m]
MAX_WHEEL_SPEED = 11  # [rad/s], inf = unlimited
BODY_RADIUS = 12  # [m], for the contact guard
DELAY_END = 13  # [s] the robot is held while t < DELAY_END (batch only; -inf = never)
ROBOT_COLUMNS = 14

#: Robots x peers per step from which :func:`advance_batch` spreads robots over threads.
PARALLEL_MIN_WORK = 4096
#: Robots per independent chunk of :func:`advance_batch` (its working set stays in cache).
CHUNK_ROBOTS = 128

# ``workqueue``, numba's fallback threading layer, aborts the process when two threads run
# parallel code at once (the service plans on a worker while other threads may simulate).
# Ask for a thread-safe layer (OpenMP or TBB) unless the user chose one (NUMBA_THREADING_LAYER).
# (numba's type stubs omit its runtime config attributes.)
if numba.config.THREADING_LAYER == "default":  # type: ignore[attr-defined]
    numba.config.THREADING_LAYER = "threadsafe"  # type: ignore[attr-defined]


# Every compiled function uses error_model="numpy": IEEE results for a division by zero
# instead of a Python exception (the maths never divides by zero on valid input, and the
# checks cost more than the step). The hot inner functions are inline="always": inlined
# into their callers by numba, without per-call overhead for array arguments.
#: Threads only where a ``prange`` says so: numba would otherwise turn array expressions
#: into parallel regions too, each one a thread wake-up (milliseconds on a busy machine).
#: (numba takes this dict of options; its type stubs only know ``parallel: bool``.)
_PRANGE_ONLY = {
    "prange": True,
    "comprehension": False,
    "setitem": False,
    "reduction": False,
    "numpy": False,
    "stencil": False,
    "fusion": False,
    "inplace_binop": False,
}


#: Whether a thread-safe threading layer loaded (set once, at the first parallel batch).
_threads = {"usable": True}


# -- the pieces of one step (scalar, compiled) ----------------------------------------------
@njit("float64(float64)", cache=True, error_model="numpy")
def wrap_to_2pi(theta: float) -> float:
    """Orientation mapped to [0, 2pi), Eq. (11.a): Python's ``theta % 2pi``, bit for bit.

    The remainder is formed directly for theta in [-4pi, 6pi): with k = floor(theta / 2pi)
    clipped to [-2, 2], k 2pi is exact and theta - k 2pi is exact for k >= 0 (Sterbenz) and,
    for k < 0, the single rounding that ``%`` also makes (exact ``fmod``, then + 2pi). A k
    misjudged by the rounded division lands outside [0, 2pi], as does any other angle or
    NaN: those take ``%`` (``fmod``, as costly as a sine). ``%`` can round a tiny negative
    angle up to exactly 2pi: the interval is kept half-open. (+ 0.0 turns -0.0 into 0.0, as
    ``%`` does, and changes nothing else.)
    """
    k = min(max(math.floor(theta / TWO_PI), -2.0), 2.0)
    wrapped = theta - k * TWO_PI + 0.0
    if not (wrapped >= 0.0 and wrapped <= TWO_PI):
        wrapped = theta % TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


@njit(inline="always", error_model="numpy")
def _heading_difference(goal_wrapped: float, theta_wrapped: float, cw: bool) -> float:
    """theta_e from headings already wrapped by (11.a): (11.b) for ccw, (21) for cw."""
    diff = goal_wrapped - theta_wrapped
    error = diff + TWO_PI if diff < 0.0 else diff  # (11.b)
    if error >= TWO_PI:
        error = 0.0
    if cw and error > 0.0:
        error -= TWO_PI  # (21)
        if error <= -TWO_PI:
            error = 0.0
    return error


@njit("float64(float64, float64, boolean)", cache=True, error_model="numpy")
def heading_error(theta_goal: float, theta: float, cw: bool) -> float:
    """Heading error theta_e = theta_r - theta_c of Eq. (5) with the law's wrap [rad].

    Both headings are wrapped by (11.a); the difference, in (-2pi, 2pi), is mapped to
    [0, 2pi) for ``ccw`` (11.b) or to (-2pi, 0] for ``cw`` (21). A difference of -1e-300
    plus 2pi rounds to 2pi: that error is really zero (and likewise onto -2pi).
    """
    return _heading_difference(wrap_to_2pi(theta_goal), wrap_to_2pi(theta), cw)


@njit("float64[::1](float64[::1])", cache=True, error_model="numpy")
def wrap_headings(theta: FloatArray) -> FloatArray:
    """:func:`wrap_to_2pi` of every element (a new array)."""
    wrapped = np.empty_like(theta)
    for i in range(theta.shape[0]):
        wrapped[i] = wrap_to_2pi(theta[i])
    return wrapped


@njit(inline="always", error_model="numpy")
def _error_in_frame(
    c: float, s: float, x: float, y: float, theta: float, goal_x: float, goal_y: float,
    goal_wrapped: float, cw: bool,
) -> tuple[float, float, float]:  # fmt: skip
    """:func:`pose_error` with c, s = cos, sin of the heading ``theta`` already at hand (the
    Euler step needs them too) and the goal heading already wrapped by (11.a)."""
    dx, dy = goal_x - x, goal_y - y
    theta_e = _heading_difference(goal_wrapped, wrap_to_2pi(theta), cw)
    return c * dx + s * dy, c * dy - s * dx, theta_e


@njit(
    "UniTuple(float64, 3)(float64, float64, float64, float64, float64, float64, boolean)",
    cache=True,
    error_model="numpy",
)
def pose_error(
    x: float, y: float, theta: float, goal_x: float, goal_y: float, goal_theta: float, cw: bool
) -> tuple[float, float, float]:
    """Posture error (x_e [m], y_e [m], theta_e [rad]): the goal in the robot frame, Eq. (5)."""
    c, s = math.cos(theta), math.sin(theta)
    return _error_in_frame(c, s, x, y, theta, goal_x, goal_y, wrap_to_2pi(goal_theta), cw)


@njit("boolean(float64, float64, float64, float64, float64)", cache=True, error_model="numpy")
def within_tolerance(
    x_e: float, y_e: float, theta_e: float, tol_position_sq: float, tol_heading: float
) -> bool:
    """The stop rule on a pre-step error: x_e^2 + y_e^2 < tol_position^2 and
    |theta_e| < tol_heading (strict)."""
    return x_e * x_e + y_e * y_e < tol_position_sq and abs(theta_e) < tol_heading


@njit(
    "UniTuple(float64, 2)(float64, float64, float64, float64, float64, float64, boolean)",
    cache=True,
    error_model="numpy",
)
def posture_law(
    x_e: float, y_e: float, theta_e: float, kx: float, ky: float, ktheta: float, cw: bool
) -> tuple[float, float]:
    """Law (17) (``cw`` False, theta_e in [0, 2pi)) or (20) (``cw`` True, theta_e in
    (-2pi, 0]): (u [m/s], omega [rad/s]).

    Both share u = kx x_e and |omega| = (ky y_e^2 + ktheta theta_e^2) e^-|theta_e|;
    omega >= 0 for (17), <= 0 for (20).
    """
    magnitude = (ky * (y_e * y_e) + ktheta * (theta_e * theta_e)) * math.exp(-abs(theta_e))
    return kx * x_e, -magnitude if cw else magnitude


@njit("float64(float64, float64, float64)", cache=True, error_model="numpy")
def repulsion_term(x_oa: float, k_avoid: float, min_x_oa: float) -> float:
    """One obstacle's term -K_avoid / x_OA of Eq. (27) [m/s], with |x_OA| floored at
    ``min_x_oa`` [m] keeping its sign (x_OA = 0 counts as ahead, so the robot backs off);
    each term is therefore bounded by K_avoid / min_x_oa."""
    guarded = max(x_oa, min_x_oa) if x_oa >= 0.0 else min(x_oa, -min_x_oa)
    return -k_avoid / guarded


@njit("UniTuple(float64, 2)(float64, float64, float64, float64)", cache=True, error_model="numpy")
def wheel_speeds(
    u: float, omega: float, wheel_radius: float, half_axle: float
) -> tuple[float, float]:
    """Right and left wheel angular speeds [rad/s] from (u, omega), inverting Eq. (2)."""
    return (u + half_axle * omega) / wheel_radius, (u - half_axle * omega) / wheel_radius


@njit("UniTuple(float64, 2)(float64, float64, float64, float64)", cache=True, error_model="numpy")
def body_velocities(
    right: float, left: float, wheel_radius: float, half_axle: float
) -> tuple[float, float]:
    """(u [m/s], omega [rad/s]) from right/left wheel speeds [rad/s], Eq. (2)."""
    return wheel_radius / 2.0 * (right + left), wheel_radius / (2.0 * half_axle) * (right - left)


@njit(
    "UniTuple(float64, 2)(float64, float64, float64, float64, float64)",
    cache=True,
    error_model="numpy",
)
def saturate(
    u: float, omega: float, wheel_radius: float, half_axle: float, max_wheel_speed: float
) -> tuple[float, float]:
    """(u, omega) divided by one factor so that neither wheel exceeds ``max_wheel_speed``
    [rad/s]: the curvature omega/u, hence the path, is kept; ``inf`` disables the limit."""
    if not max_wheel_speed < math.inf:
        return u, omega  # no limit: nothing to compute
    right, left = wheel_speeds(u, omega, wheel_radius, half_axle)
    peak = max(abs(right), abs(left))
    if peak > max_wheel_speed:
        scale = max_wheel_speed / max(peak, 1e-300)
        return u * scale, omega * scale
    return u, omega


@njit(inline="always", error_model="numpy")
def _euler(
    x: float, y: float, theta: float, c: float, s: float, u: float, omega: float, dt: float
) -> tuple[float, float, float]:
    """Forward Euler on Eq. (3) with c, s = cos, sin of the pre-step heading ``theta``."""
    return x + c * u * dt, y + s * u * dt, theta + omega * dt


# -- THE step ---------------------------------------------------------------------------------
class StepResult(NamedTuple):
    """One step of one robot: pre-step error, stop rule, applied control, next posture."""

    x_e: float  # [m] pre-step error, Eq. (5), robot frame
    y_e: float  # [m]
    theta_e: float  # [rad], law's wrap
    done: bool  # pre-step error within tolerance (the step is still applied)
    u: float  # [m/s] applied (after repulsion, saturation and contact guard)
    omega: float  # [rad/s]
    right: float  # [rad/s] wheel speeds of (u, omega), Eq. (2)
    left: float
    repulsion: float  # [m/s] Eq. (27) sum added to u before saturation
    avoiding: bool  # a peer or obstacle is within its influence radius, or the guard acted
    x: float  # posture after the Euler step [m, m, rad]
    y: float
    theta: float


@njit(inline="always", error_model="numpy")
def robot_step(
    x: float,
    y: float,
    theta: float,
    params: FloatArray,
    i: int,
    hold: bool,
    positions: FloatArray,
    peer_lo: int,
    peer_hi: int,
    skip: int,
    obstacles: FloatArray,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    dt: float,
) -> tuple[float, float, float, bool, float, float, float, float, float, bool, float, float, float]:
    """One closed-loop step of robot ``params[i]`` at (x, y, theta) (see the module docstring).

    Peers are columns ``peer_lo .. peer_hi - 1`` of ``positions`` except ``skip`` (the robot
    itself in a batch, -1 otherwise). Returns the fields of :class:`StepResult`.
    """
    c, s = math.cos(theta), math.sin(theta)
    cw = params[i, CW] != 0.0
    x_e, y_e, theta_e = _error_in_frame(
        c, s, x, y, theta, params[i, GOAL_X], params[i, GOAL_Y], params[i, GOAL_HEADING], cw
    )
    done = within_tolerance(x_e, y_e, theta_e, params[i, TOL_POSITION_SQ], params[i, TOL_HEADING])
    r, b = params[i, WHEEL_RADIUS], params[i, HALF_AXLE]
    if hold:
        return x_e, y_e, theta_e, done, 0.0, 0.0, 0.0, 0.0, 0.0, False, x, y, theta

    u, omega = posture_law(x_e, y_e, theta_e, params[i, KX], params[i, KY], params[i, KTHETA], cw)
    repulsion = 0.0
    avoiding = False
    close_ahead = close_behind = False  # a peer within contact range ahead / behind
    if k_avoid > 0.0:
        influence_sq = peer_radius * peer_radius
        contact = 2.0 * params[i, BODY_RADIUS] + min_x_oa
        contact_sq = contact * contact
        for j in range(peer_lo, peer_hi):
            if j == skip:
                continue
            dx, dy = positions[0, j] - x, positions[1, j] - y
            d_sq = dx * dx + dy * dy
            if d_sq < influence_sq or d_sq < contact_sq:
                x_oa = c * dx + s * dy  # Eq. (26), first row
                if d_sq < influence_sq:
                    repulsion += repulsion_term(x_oa, k_avoid, min_x_oa)
                    avoiding = True
                if d_sq < contact_sq:
                    close_ahead |= x_oa > 0.0
                    close_behind |= x_oa < 0.0
        for j in range(obstacles.shape[1]):
            dx, dy = obstacles[0, j] - x, obstacles[1, j] - y
            if dx * dx + dy * dy < obstacles[2, j] * obstacles[2, j]:
                repulsion += repulsion_term(c * dx + s * dy, k_avoid, min_x_oa)
                avoiding = True
    u, omega = saturate(u + repulsion, omega, r, b, params[i, MAX_WHEEL_SPEED])
    if (u > 0.0 and close_ahead) or (u < 0.0 and close_behind):
        u = 0.0  # contact guard: turn on the spot, never drive into a peer
        avoiding = True
    right, left = wheel_speeds(u, omega, r, b)
    nx, ny, ntheta = _euler(x, y, theta, c, s, u, omega, dt)
    return x_e, y_e, theta_e, done, u, omega, right, left, repulsion, avoiding, nx, ny, ntheta


_STEP_RESULT = "Tuple((float64, float64, float64, boolean, float64, float64, float64, float64, float64, boolean, float64, float64, float64))"  # noqa: E501


@njit(
    _STEP_RESULT + "(float64, float64, float64, float64[:, ::1], boolean, float64[:, ::1], "
    "float64[:, ::1], float64, float64, float64, float64)",
    cache=True,
    error_model="numpy",
)
def _step_robot(
    x: float,
    y: float,
    theta: float,
    params: FloatArray,
    hold: bool,
    peers: FloatArray,
    obstacles: FloatArray,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    dt: float,
) -> tuple[float, float, float, bool, float, float, float, float, float, bool, float, float, float]:
    return robot_step(
        x, y, theta, params, 0, hold, peers, 0, peers.shape[1], -1, obstacles,
        k_avoid, peer_radius, min_x_oa, dt,
    )  # fmt: skip


def step_robot(
    pose: tuple[float, float, float],
    params: FloatArray,
    *,
    hold: bool = False,
    peers: FloatArray,
    obstacles: FloatArray,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    dt: float = 0.0,
) -> StepResult:
    """One step of one robot (the agent's tick): :func:`robot_step` on ``params`` (1, 14).

    ``peers`` (2, M) and ``obstacles`` (3, K) are C-contiguous float64 rows (see the module
    docstring). ``dt`` [s] only moves the returned posture (0: it stays).
    """
    return StepResult(
        *_step_robot(
            float(pose[0]), float(pose[1]), float(pose[2]), params, hold, peers, obstacles,
            k_avoid, peer_radius, min_x_oa, dt,
        )
    )  # fmt: skip


@njit(
    "UniTuple(float64, 3)(float64, float64, float64, float64, float64, float64, float64, "
    "float64, int64)",
    cache=True,
    error_model="numpy",
)
def integrate_wheels(
    x: float,
    y: float,
    theta: float,
    right: float,
    left: float,
    wheel_radius: float,
    half_axle: float,
    dt: float,
    steps: int,
) -> tuple[float, float, float]:
    """``steps`` forward-Euler steps of ``dt`` [s] under constant wheel speeds [rad/s]: the
    simulated drive's unicycle, the same Euler update as :func:`robot_step`."""
    u, omega = body_velocities(right, left, wheel_radius, half_axle)
    for _ in range(steps):
        x, y, theta = _euler(x, y, theta, math.cos(theta), math.sin(theta), u, omega, dt)
    return x, y, theta


def robot_params(
    goal: FloatArray,
    gains: FloatArray,
    cw: FloatArray,
    tol_position: FloatArray,
    tol_heading: FloatArray,
    wheel_radius: FloatArray,
    half_axle: FloatArray,
    max_wheel_speed: FloatArray,
    body_radius: FloatArray,
    delay_end: FloatArray | None = None,
) -> FloatArray:
    """Parameter rows (N, ``ROBOT_COLUMNS``) from per-robot columns (N,) and goal/gains (N, 3).

    ``delay_end`` [s]: the batch holds robot i while t < delay_end[i] (None: never).
    """
    n = goal.shape[0]
    params = np.empty((n, ROBOT_COLUMNS))
    params[:, GOAL_X] = goal[:, 0]
    params[:, GOAL_Y] = goal[:, 1]
    params[:, GOAL_HEADING] = wrap_headings(np.ascontiguousarray(goal[:, 2], dtype=np.float64))
    params[:, CW] = cw
    params[:, KX : KTHETA + 1] = gains
    params[:, TOL_POSITION_SQ] = tol_position * tol_position
    params[:, TOL_HEADING] = tol_heading
    params[:, WHEEL_RADIUS] = wheel_radius
    params[:, HALF_AXLE] = half_axle
    params[:, MAX_WHEEL_SPEED] = max_wheel_speed
    params[:, BODY_RADIUS] = body_radius
    params[:, DELAY_END] = -np.inf if delay_end is None else delay_end
    return params


# -- N robots, many steps ---------------------------------------------------------------------
class Interaction(NamedTuple):
    """How the robots of a batch act on each other: within blocks of ``group`` consecutive
    robots, through Eq. (27) with K_avoid [m^2/s] inside ``peer_radius`` [m] (x_OA guard
    ``min_x_oa`` [m]) and the contact guard; not at all unless K_avoid > 0 and
    ``peer_radius`` > 0. K_avoid and ``min_x_oa`` act on static obstacles too."""

    group: int
    k_avoid: float
    peer_radius: float
    min_x_oa: float


@njit("boolean(int64, float64, float64)", cache=True, error_model="numpy")
def interacting(group: int, k_avoid: float, peer_radius: float) -> bool:
    """Whether the robots of a batch act on each other at all (see :class:`Interaction`)."""
    return k_avoid > 0.0 and peer_radius > 0.0 and group > 1


class Schedule(NamedTuple):
    """Which steps a call of :func:`advance_batch` takes: up to ``max_steps`` of ``dt`` [s]
    from step ``first_step``, recording every ``record_every``-th step."""

    dt: float
    first_step: int
    max_steps: int
    record_every: int = 1


# Rows of the per-robot metrics (2, N): Eq. (25) control effort int(|u| + |omega|) dt and
# distance int |u| dt [m].
EFFORT = 0
DISTANCE = 1
#: Columns of a recorded step (rows, N, RECORD_COLUMNS): pre-step pose (x, y, theta),
#: applied control (u, omega), pre-step error (x_e, y_e, theta_e).
RECORD_COLUMNS = 8


@njit(inline="always", error_model="numpy")
def _advance_robot(
    i: int,
    step: int,
    t: float,
    current: FloatArray,
    following: FloatArray,
    params: FloatArray,
    done_step: np.ndarray,
    metrics: FloatArray,
    obstacles: FloatArray,
    peer_lo: int,
    peer_hi: int,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    dt: float,
    record: FloatArray,
    row: int,
) -> int:
    """Robot i's step ``step`` (time ``t`` = step dt [s]) from ``current`` into
    ``following`` (both (3, N)), with peers ``peer_lo .. peer_hi - 1``; returns 1 if the
    stop rule fired. ``row`` >= 0 records the step in that row of ``record``."""
    x, y, theta = current[0, i], current[1, i], current[2, i]
    moving = done_step[i] < 0
    if not moving and row < 0:  # done: stands still (still a peer of the others)
        following[0, i], following[1, i], following[2, i] = x, y, theta
        return 0
    hold = t < params[i, DELAY_END]
    r = robot_step(
        x, y, theta, params, i, hold, current, peer_lo, peer_hi, i, obstacles,
        k_avoid, peer_radius, min_x_oa, dt,
    )  # fmt: skip
    finished = 0
    u = omega = 0.0
    if moving:
        u, omega = r[4], r[5]
        metrics[EFFORT, i] += (abs(omega) + abs(u)) * dt  # Eq. (25)
        metrics[DISTANCE, i] += abs(u) * dt
        following[0, i], following[1, i], following[2, i] = r[10], r[11], r[12]
        if r[3]:
            done_step[i] = step
            finished = 1
    else:
        following[0, i], following[1, i], following[2, i] = x, y, theta
    if row >= 0:
        record[row, i, 0], record[row, i, 1], record[row, i, 2] = x, y, theta
        record[row, i, 3], record[row, i, 4] = u, omega
        record[row, i, 5], record[row, i, 6], record[row, i, 7] = r[0], r[1], r[2]
    return finished


@njit(cache=True, error_model="numpy")
def lower_min_separation(
    positions: FloatArray, group: int, min_pair_sq: FloatArray, first_block: int, end_block: int
) -> None:
    """Lower ``min_pair_sq`` (blocks, group, group) to the squared centre distances [m^2]
    of every pair within blocks ``first_block .. end_block - 1`` of ``group`` consecutive
    robots."""
    for block in range(first_block, end_block):
        base = block * group
        for a in range(group):
            for b in range(a + 1, group):
                dx = positions[0, base + a] - positions[0, base + b]
                dy = positions[1, base + a] - positions[1, base + b]
                d_sq = dx * dx + dy * dy
                if d_sq < min_pair_sq[block, a, b]:
                    min_pair_sq[block, a, b] = d_sq
                    min_pair_sq[block, b, a] = d_sq


@njit(cache=True, error_model="numpy")
def advance_chunk(
    lo: int,
    hi: int,
    pose: FloatArray,
    spare: FloatArray,
    params: FloatArray,
    done_step: np.ndarray,
    metrics: FloatArray,
    obstacles: FloatArray,
    interaction: Interaction,
    schedule: Schedule,
    record: FloatArray,
    min_pair_sq: FloatArray,
) -> int:
    """Robots ``lo .. hi - 1`` for up to ``max_steps`` steps from step ``first_step``;
    returns the steps taken until all of them were done (see :func:`advance_batch`).

    Once every robot of the chunk is done nothing in it changes any more, so it stops
    there -- unless recording, which goes on to the end of the call (standing rows)."""
    group, k_avoid, peer_radius, min_x_oa = interaction
    dt, first_step, max_steps, record_every = schedule
    peers = interacting(group, k_avoid, peer_radius)
    span = group if peers else max(hi - lo, 1)
    remaining = 0
    for i in range(lo, hi):
        remaining += 1 if done_step[i] < 0 else 0
    recording = record.shape[0] > 0
    first_row = (first_step + record_every - 1) // record_every
    current, following = pose, spare
    taken = ran = 0
    for step in range(first_step, first_step + max_steps):
        if remaining == 0:
            if not recording:
                break
        else:
            taken += 1
        if min_pair_sq.shape[0] > 0:
            lower_min_separation(current, group, min_pair_sq, lo // group, hi // group)
        row = -1
        if recording and step % record_every == 0:
            row = step // record_every - first_row
        t = step * dt
        for base in range(lo, hi, span):  # blocks of peers (the whole chunk without peers)
            end = min(base + span, hi)
            peer_hi = end if peers else base
            for i in range(base, end):
                remaining -= _advance_robot(
                    i, step, t, current, following, params, done_step, metrics, obstacles,
                    base, peer_hi, k_avoid, peer_radius, min_x_oa, dt, record, row,
                )  # fmt: skip
        current, following = following, current
        ran += 1
    if ran % 2 == 1:
        for i in range(lo, hi):
            pose[0, i], pose[1, i], pose[2, i] = spare[0, i], spare[1, i], spare[2, i]
    return taken


@njit(cache=True, parallel=_PRANGE_ONLY, error_model="numpy")  # type: ignore[call-overload,untyped-decorator]
def _advance_chunks_in_parallel(chunk: int, n: int, *args: Any) -> int:
    """:func:`advance_chunk` on consecutive chunks of ``chunk`` of the ``n`` robots, spread
    over the threads (``args``: its arguments after ``lo, hi``); returns the most steps any
    chunk took."""
    pose, spare, params, done_step, metrics, obstacles, interaction, schedule, record, pairs = args
    # The threads get scalars and arrays only (parfors take no named tuples).
    group, k_avoid, peer_radius, min_x_oa = interaction
    dt, first_step, max_steps, record_every = schedule
    chunks = (n + chunk - 1) // chunk
    taken = np.zeros(chunks, dtype=np.int64)
    for c in prange(chunks):
        taken[c] = advance_chunk(
            c * chunk, min(n, (c + 1) * chunk), pose, spare, params, done_step, metrics,
            obstacles, Interaction(group, k_avoid, peer_radius, min_x_oa),
            Schedule(dt, first_step, max_steps, record_every), record, pairs,
        )  # fmt: skip
    most = 0
    for c in range(chunks):
        most = max(most, taken[c])
    return most


def advance_batch(
    pose: FloatArray,
    params: FloatArray,
    done_step: npt.NDArray[np.int64],
    metrics: FloatArray,
    obstacles: FloatArray,
    interaction: Interaction,
    schedule: Schedule,
    record: FloatArray | None = None,
    min_pair_sq: FloatArray | None = None,
) -> int:
    """Advance N robots as ``schedule`` says, stopping when every robot is done; returns the
    steps taken (until the last one was done).

    ``pose`` (3, N) is updated in place; robots read their peers' pre-step positions and
    interact (Eq. 27 and the contact guard) as ``interaction`` says. Per robot:
    ``done_step`` (-1 while moving, then the step the stop rule fired; a done robot stands
    still) and ``metrics`` (``EFFORT``, ``DISTANCE``) accumulate. ``record`` (rows, N,
    ``RECORD_COLUMNS``) takes every step k with k % record_every == 0 of this call, in
    order; ``min_pair_sq`` (blocks, group, group) the smallest pre-step squared separations.

    Robots are simulated in independent chunks (whole blocks when they interact or
    separations are tracked), each through all its steps; large batches spread the chunks
    over the threads, so no thread waits for another between steps.
    """
    n = pose.shape[1]
    record = np.zeros((0, n, RECORD_COLUMNS)) if record is None else record
    min_pair_sq = np.zeros((0, 0, 0)) if min_pair_sq is None else min_pair_sq
    group = interaction.group
    peers = interacting(group, interaction.k_avoid, interaction.peer_radius)
    unit = group if peers or min_pair_sq.shape[0] > 0 else 1
    chunk = unit * max(1, CHUNK_ROBOTS // unit)
    spare = np.empty_like(pose)
    args = (pose, spare, params, done_step, metrics, obstacles, interaction, schedule, record,
            min_pair_sq)  # fmt: skip
    if n > chunk and n * (group if peers else 1) >= PARALLEL_MIN_WORK and _threads["usable"]:
        try:
            return int(_advance_chunks_in_parallel(chunk, n, *args))
        except ValueError as error:  # raised while compiling, before any step ran
            if "threading layer" not in str(error):
                raise
            _threads["usable"] = False  # no OpenMP or TBB here: one thread it is
    return max(
        (int(advance_chunk(lo, min(n, lo + chunk), *args)) for lo in range(0, n, chunk)),
        default=0,
    )
