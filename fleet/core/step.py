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
   static obstacle whose core (a post's centre, a wall segment's closest point) is closer
   than its influence radius; x_OA (Eq. 26, that point's coordinate along the heading) is
   floored at ``min_x_oa`` keeping its sign (0 counts as ahead) -- or, with the robot's
   ``SMOOTHING`` w > 0 (the fleet's default), the term made continuous: linear through 0
   near abeam and faded in over the outer w of the radius (:func:`repulsion_term`);
6. saturation: u and omega divided by the same factor so that neither wheel of Eq. (2)
   exceeds ``max_wheel_speed`` (the curvature omega/u is kept);
7. safety filter (:func:`safety_filter`, when ``safety.margin`` >= 0): the command changed as
   little as possible so that no body comes within ``margin`` of another's (see below);
   then saturated again;
8. forward Euler on Eq. (3) with the pre-step heading: x += cos(theta) u dt, ...

Step 5 is on only when K_avoid > 0; step 7 whenever the filter is on (the paper's model
runs without it).

**Routes.** A robot may follow a route: a table of its via-points, then its goal, that it
aims at in turn. Before each step, on the pre-step pose, it passes every via-point it is
within the pass-through radius of and aims at the next entry (:func:`aim`; the agent calls
it before its tick's step, the batch before each step): a via-point facing it, with the law
that turns the shorter way; the goal with the task's law. The stop rule then applies to the
goal only (the radius is at least the position tolerance).

**The safety filter** (a discrete-time control barrier function on the unicycle, the
Robotarium's barrier certificates with the projected point). The point p = c + l e(theta)
ahead of the axle centre c moves, in one Euler step, by dt (u e + l omega e_perp) plus a
second-order term, so in v = (u, l omega) the motion is linear. A robot's *disc* (radius
R + l around p) holds its body. For a peer j (its disc predicted at the instant the
command acts, with an uncertainty ``spread`` E [m]: pose error and the motion it may have
made since it was seen) and a static obstacle (the closest point of its segment, body
radius: the distance to a segment is convex in p, so its linearisation never overstates the
clearance, as for a point), with clearance
C = |p_i - p_j| - (R_i + l) - (R_j + l) - margin, the robot keeps its *closing speed*
along every direction within E of the estimated one to at most share * rate * (C_lo - eps):
share 1/2 for a peer (the peer takes the other half: every robot runs this filter), 1 for
a static body; C_lo = C - E (a lower bound of the true clearance); the cone is widened
by the robot's own heading uncertainty ``heading`` (its velocity may point that far off: a
predicted heading, docs/safety.md; such a cone counts as every direction only from 90
degrees on: its two edges and its middle, n . v <= bound cos phi, hold the cone below
that); eps [m] the allowance for the second-order terms (the projected point's rotation
within a step and the drive's arc), eps = (l W^2 + V W) dt / rate with V = (1 +
``SIDE_STEP``) |v0| the longest the result can be and W the turn-rate bound (wheel limit,
or V / l). With rate * dt <= 1 the
clearance of every pair then never falls below 0 from one step to the next:
C' >= (1 - rate dt) C (derivation in the docs/safety.md).
The constraints are half-planes a . v <= c with unit a; the command is the point of
their intersection closest to the nominal v0 in du^2 + k^2 dw^2 (two variables: the
nominal, each edge's projection or each vertex, the closest feasible one wins -- exact, no
solver), or a standstill when none is feasible (standing still never closes a gap); k = 1
with a static body in range (turn along it), ``TURN_PRICE`` b / l (at least 1) among
peers only (slow down before swerving: :func:`_turn_cost`); a result longer than V is
scaled back to V (feasible: every constraint holds 0; else a standstill). Bodies whose
constraint cannot bind (c >= V) are skipped -- a peer by its centre's distance, before
its projected point is computed (|p_i - p_j| is within 2 l of it). When it binds, the
aim is shifted sideways by ``SIDE_STEP`` |v0| in the law's rotation sense (robots meeting
head-on pass each other) -- but on a leg to a via-point (``ON_VIA``) with one peer binding
and nothing else, away from that peer, seen from the straight way to the via-point (the
law's sense when the peer is within ``SIDE_TIE_M`` of the way): the law facing a
via-point turns the shorter way, so its sense flips as the via-point crosses dead ahead,
and a robot routed past a standing peer turned back and forth at it for good; among
several peers the law's common sense keeps a crowd turning one way (away from the nearest
one, crowds of swapping robots turned back and forth; docs/benchmarks.md, thirtieth
stop). Running along a wall (a wall segment in range whose closest point is within 30
degrees of abeam: the heading within 30 degrees of the wall) the
command also turns no faster than ``HELD_TURN_RATE`` or the nominal, whichever is more,
when some command that does not reverse allows it (two more half-planes |w| <= l
max(HELD_TURN_RATE, |omega0|); else the closest without them): a turn at the point 3 cm
ahead is cheap in the metric, and the filter answered a heading 0.27 rad off a corridor's
axis with 7 rad/s, which command latency carried past the axis into a heading oscillation
-- along a wall it slows down instead. Round a post, or facing a wall, the turn is the way
past (capped there too, it slowed case III and the car parks). The turn of a command it
changed is then capped at the nominal path's curvature at the speed it keeps (|omega0| |u|
/ |u0|) or ``HELD_TURN_RATE``, whichever is more, as far as the constraints allow at that
u (:func:`_held_turn`): a body ahead bounds u only, and a held robot used to spin in place
at the wheel limit.


**Numerics.** IEEE double arithmetic in a fixed order with libm's ``sin``, ``cos`` and ``exp``
(the functions Python's :mod:`math` calls), no fastmath and no fused multiply-add, so a step
equals the plain-Python reference bit for bit when both sum in the same order. The wrap
(11.a) forms the exact remainder theta - k 2pi directly (see :func:`wrap_to_2pi`).

**Data.** A robot is a row of ``params`` (columns ``GOAL_X`` ... ``DELAY_END``, built by
:func:`robot_params`); positions are rows: ``positions[0]`` = x, ``positions[1]`` = y [m];
static obstacles are capsules (rows ``OBSTACLE_X`` ... ``END_Y``): the segment from
(x, y) to its end (a post when the two coincide: a wall is a chain of them), the influence
radius of Eq. (27) and the body radius around the segment [m]; peers are columns of
``positions`` (rows x, y, theta) with ``shapes[0]`` = body radius and ``shapes[1]`` = spread E [m].

**Compilation.** Every function is compiled with ``cache=True`` (machine code kept in this
package's ``__pycache__``, or numba's per-user cache directory when that is read-only).
The entry points of the agent and the drive carry explicit signatures: they are compiled,
or loaded from the cache, when this module is imported -- never inside a control tick --
and a call with other types raises instead of compiling. The batch kernel compiles at a
process's first batch simulation; the parallel kernel of large batches (the whole step
inlined again under ``prange``: about a minute's compile) at its first large batch --
except in a process that defers it (:func:`defer_parallel_kernel`: the planner's), whose
large batches run on one thread, with the same results, until another thread has built it
(``fleet.core.simulate.warm_parallel_kernel``). All compiled code lives in this one file
on purpose: numba's cache is invalidated by a change of the file a function was compiled
from, not by changes in the files it calls into.
"""

from __future__ import annotations

import math
from collections.abc import Callable
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
BODY_RADIUS = 12  # [m], the body, for the safety filter
DELAY_END = 13  # [s] the robot is held while t < DELAY_END (batch only; -inf = never)
ROUTE_LAST = 14  # column of the robot's goal in the route table (batch only; -1: no route)
PASS_SQ = 15  # squared pass-through radius [m^2] of the route's via-points
SMOOTHING = 16  # [m] width of Eq. (27)'s smoothed bands (0: the paper's term; repulsion_term)
ON_VIA = 17  # 1.0 while the robot aims at a via-point of its route, not its goal (aim)
ROBOT_COLUMNS = 18

# Rows of a route table (``route[:, k]``): the points a robot aims at in turn, its via-points
# then its goal (world frame). A robot aims at entry k until its centre comes within the
# pass-through radius of it (:func:`aim`); the last entry is its goal (the stop rule).
VIA_X = 0  # [m]
VIA_Y = 1
VIA_HEADING = 2  # [rad] the goal's heading, wrapped by (11.a) (unused at a via-point)
VIA_CW = 3  # the goal's law: 1.0 clockwise (20), 0.0 (17) (unused at a via-point)
ROUTE_ROWS = 4

# Rows of the static obstacles (``obstacles[:, j]``): a capsule, the segment from (X, Y) to
# (END_X, END_Y) (a post when both ends coincide) inflated by BODY; Eq. (27) acts within
# INFLUENCE of the segment. An array of only the first four rows holds posts.
OBSTACLE_X = 0  # [m] world frame
OBSTACLE_Y = 1
INFLUENCE = 2  # [m] influence radius of Eq. (27), around the segment
BODY = 3  # [m] body radius (half a wall's thickness), for the safety filter
END_X = 4  # [m] the segment's far end
END_Y = 5
OBSTACLE_ROWS = 6

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


#: The parallel kernel in this process: whether it is compiled (or loaded from numba's
#: cache) and why it is unusable. Its compile takes about a minute on a fresh install (the
#: whole step inlined again under ``prange``): a process that must not wait for it (the
#: planner's) defers it -- its large batches run on one thread until another thread has
#: built it (:func:`defer_parallel_kernel`); otherwise the first large batch builds it.
_parallel = {"ready": False, "error": ""}
#: Empty: not deferred; else how to build the kernel off the batch's thread, until the
#: first large batch calls it (then None: it is called once).
_deferral: list[Callable[[], None] | None] = []


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


@njit(
    "float64(float64, float64, float64, float64, float64, float64)",
    cache=True,
    error_model="numpy",
)
def repulsion_term(
    x_oa: float,
    distance_sq: float,
    influence: float,
    k_avoid: float,
    min_x_oa: float,
    smoothing: float,
) -> float:
    """One obstacle's term of Eq. (27) [m/s]: x_OA [m] (Eq. 26) of a core ``distance_sq``
    [m^2] away, inside its ``influence`` radius [m].

    ``smoothing`` = 0: the paper's -K_avoid / x_OA with |x_OA| floored at ``min_x_oa`` [m]
    keeping its sign (x_OA = 0 counts as ahead, so the robot backs off); bounded by
    K_avoid / min_x_oa. ``smoothing`` = w > 0 [m]: the same term made continuous, so that
    pose noise at a band's edge cannot flip the robot's speed from tick to tick: linear
    through 0 for |x_OA| < g = max(w, ``min_x_oa``) (-K_avoid x_OA / g^2: nothing for a
    core abeam), and faded in linearly over the outer w of the influence radius (nothing
    at its edge); bounded by K_avoid / g.
    """
    if smoothing <= 0.0:
        guarded = max(x_oa, min_x_oa) if x_oa >= 0.0 else min(x_oa, -min_x_oa)
        return -k_avoid / guarded
    band = max(smoothing, min_x_oa)
    term = -k_avoid * x_oa / (band * band) if abs(x_oa) < band else -k_avoid / x_oa
    return min(1.0, (influence - math.sqrt(distance_sq)) / smoothing) * term


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


# -- the safety filter (scalar, compiled) ----------------------------------------------------
class Safety(NamedTuple):
    """Safety filter parameters (module docstring): ``margin`` [m] between bodies (< 0: the
    filter is off, the paper's model), ``projection`` l [m] of the point ahead of the axle,
    ``rate`` [1/s] of the barrier (clearance may shrink by at most rate dt per step; capped
    at 1 / dt), ``spread`` [m], this robot's own pose uncertainty at the instant its
    command acts (pose error, latency prediction), and ``heading`` [rad], its heading's:
    its velocity may point that far from where the step thinks, so every body's cone of
    directions is widened by it."""

    margin: float
    projection: float
    rate: float
    spread: float
    heading: float = 0.0


#: The paper's model: no filter.
SAFETY_OFF = Safety(-1.0, 0.0, 0.0, 0.0, 0.0)
#: Half-planes one filter call may hold (3 per body; beyond: standstill, which is safe).
MAX_CONSTRAINTS = 48
_SQRT_HALF = math.sqrt(0.5)
_FEASIBLE_TOL = 1e-12  # [m/s] slack of a constraint check
_CULL_SLACK = 1e-6  # [m] beyond rounding: a culled body is one whose constraint is skipped
#: Sideways aim of a bound command, a fraction of |v0| in l omega (its side: module docstring).
SIDE_STEP = 0.5
#: [m] on a via leg, the one binding peer's centre within this of the straight way to
#: the via-point is dead ahead: the sideways aim keeps the law's sense (module docstring).
SIDE_TIE_M = 0.05
#: Share of the wheels' price of a turn (b domega) in the filter's metric among peers.
TURN_PRICE = 0.5


@njit(inline="always", error_model="numpy")
def _add_half_plane(cons: FloatArray, n: int, a1: float, a2: float, bound: float) -> int:
    """Append a1 u + a2 w <= bound to ``cons``; returns the new count (-1 when full)."""
    if n < 0 or n >= cons.shape[0]:
        return -1
    cons[n, 0], cons[n, 1], cons[n, 2] = a1, a2, bound
    return n + 1


@njit(inline="always", error_model="numpy")
def _add_body(
    cons: FloatArray, n: int, dx: float, dy: float, c: float, s: float, gap: float,
    spread: float, heading: float, share_rate: float, reach: float,
) -> tuple[int, bool]:  # fmt: skip
    """The half-planes of one body at (dx, dy) [m] from the own projected point (heading
    cos c, sin s): closing speed <= share_rate (gap - spread) in every direction within
    ``spread`` of the estimated one, widened by the own ``heading`` uncertainty [rad].
    ``gap`` = |(dx, dy)| - radii - margin - eps [m]. Returns the new count and whether only
    a standstill is safe. Skipped when it cannot bind (its bound >= ``reach`` = |v0|)."""
    bound = share_rate * (gap - spread)
    if bound >= reach:
        return n, False
    distance = math.sqrt(dx * dx + dy * dy)
    sin_phi = cos_phi = 0.0
    wide = distance <= 0.0
    if heading > 0.0 and not wide:
        phi = math.asin(min(max(spread, 0.0) / distance, 1.0)) + heading
        wide = phi >= 0.5 * math.pi  # the edges and the middle hold any cone below 90 deg
        sin_phi, cos_phi = math.sin(phi), math.cos(phi)
    elif not wide:
        wide = spread >= _SQRT_HALF * distance
    if wide:
        # Any direction (or too uncertain a one for the cone): |v| <= bound.
        if bound <= 0.0:
            return n, True
        inner = bound * _SQRT_HALF  # the square inside the disc |v| <= bound
        n = _add_half_plane(cons, n, 1.0, 0.0, inner)
        n = _add_half_plane(cons, n, -1.0, 0.0, inner)
        n = _add_half_plane(cons, n, 0.0, 1.0, inner)
        n = _add_half_plane(cons, n, 0.0, -1.0, inner)
        return n, n < 0
    mx, my = dx / distance, dy / distance
    a1, a2 = c * mx + s * my, c * my - s * mx  # towards the body, in (u, l omega)
    if heading <= 0.0:
        if spread <= 0.0:
            n = _add_half_plane(cons, n, a1, a2, bound)
            return n, n < 0
        sin_phi = spread / distance
        cos_phi = math.sqrt(1.0 - sin_phi * sin_phi)
    n = _add_half_plane(cons, n, a1 * cos_phi - a2 * sin_phi, a2 * cos_phi + a1 * sin_phi, bound)
    n = _add_half_plane(cons, n, a1 * cos_phi + a2 * sin_phi, a2 * cos_phi - a1 * sin_phi, bound)
    if bound > 0.0:
        n = _add_half_plane(cons, n, a1, a2, bound * cos_phi)
    return n, n < 0


@njit(inline="always", error_model="numpy")
def _closest_offset(
    ax: float, ay: float, bx: float, by: float, px: float, py: float
) -> tuple[float, float]:
    """(dx, dy) [m] from (px, py) to the closest point of the segment from a to b."""
    ex, ey = bx - ax, by - ay
    length_sq = ex * ex + ey * ey
    t = 0.0
    if length_sq > 0.0:
        t = min(max(((px - ax) * ex + (py - ay) * ey) / length_sq, 0.0), 1.0)
    return ax + t * ex - px, ay + t * ey - py


@njit(inline="always", error_model="numpy")
def obstacle_offset(obstacles: FloatArray, j: int, px: float, py: float) -> tuple[float, float]:
    """(dx, dy) [m] from (px, py) to the closest point of obstacle ``j``'s core: its centre,
    or, with rows ``END_X``/``END_Y``, the closest point of the segment from (x, y) to the
    end (a wall; a zero-length segment is a post)."""
    ax, ay = obstacles[0, j], obstacles[1, j]
    if obstacles.shape[0] <= END_Y:
        return ax - px, ay - py
    return _closest_offset(ax, ay, obstacles[END_X, j], obstacles[END_Y, j], px, py)


@njit(inline="always", error_model="numpy")
def _satisfies(cons: FloatArray, n: int, u: float, w: float) -> bool:
    for k in range(n):  # noqa: SIM110 (a loop numba compiles)
        if cons[k, 0] * u + cons[k, 1] * w > cons[k, 2] + _FEASIBLE_TOL:
            return False
    return True


@njit(inline="always", error_model="numpy")
def closest_feasible(
    cons: FloatArray, n: int, u0: float, w0: float, turn_cost: float
) -> tuple[float, float]:
    """The point of {a . v <= c} (rows of ``cons``) closest to (u0, w0) in the metric
    du^2 + ``turn_cost`` dw^2: the nominal if feasible, else the closest feasible edge
    projection or vertex; (0, 0) if none is."""
    if _satisfies(cons, n, u0, w0):
        return u0, w0
    best_u = best_w = 0.0
    best = math.inf
    for k in range(n):
        excess = cons[k, 0] * u0 + cons[k, 1] * w0 - cons[k, 2]
        if excess > 0.0:
            a2 = cons[k, 1] / turn_cost  # the edge's normal in the metric
            t = excess / (cons[k, 0] * cons[k, 0] + cons[k, 1] * a2)
            cu, cw = u0 - t * cons[k, 0], w0 - t * a2
            d = (cu - u0) * (cu - u0) + turn_cost * ((cw - w0) * (cw - w0))
            if d < best and _satisfies(cons, n, cu, cw):
                best, best_u, best_w = d, cu, cw
    for k in range(n):
        for m in range(k + 1, n):
            det = cons[k, 0] * cons[m, 1] - cons[k, 1] * cons[m, 0]
            if abs(det) < 1e-12:
                continue
            cu = (cons[k, 2] * cons[m, 1] - cons[k, 1] * cons[m, 2]) / det
            cw = (cons[k, 0] * cons[m, 2] - cons[k, 2] * cons[m, 0]) / det
            d = (cu - u0) * (cu - u0) + turn_cost * ((cw - w0) * (cw - w0))
            if d < best and _satisfies(cons, n, cu, cw):
                best, best_u, best_w = d, cu, cw
    return best_u, best_w


@njit(inline="always", error_model="numpy")
def _turn_cost(half_axle: float, ahead: float, peers_only: bool) -> float:
    """The weight of dw^2 beside du^2 in the filter's metric (w = l omega). Among peers
    only: (``TURN_PRICE`` b / l)^2, a share of the wheels' own price of a turn (du^2 + b^2
    domega^2 is half the sum of the wheels' squared changes, times r^2): a peer moves on,
    so slowing down is the better answer, and a turn priced at the point's speed makes a
    two-tick limit cycle in omega against a standing peer. With a static body in range:
    1, so that the robot turns along a post or a wall instead of stopping at it."""
    if not peers_only or ahead <= 0.0:
        return 1.0
    k = TURN_PRICE * half_axle / ahead
    return max(k * k, 1.0)


@njit(inline="always", error_model="numpy")
def _within_reach(
    cons: FloatArray, n: int, u: float, w: float, reach: float, ahead: float, omega0: float
) -> tuple[float, float, bool]:
    """The filter's (u, omega, True) from its (u, w = l omega), shortened to ``reach``
    (the second-order allowance eps assumes |v| <= reach): scaled towards 0 when 0 is
    feasible (the constraints are convex), else a standstill."""
    length_sq = u * u + w * w
    if length_sq > reach * reach:
        if not _satisfies(cons, n, 0.0, 0.0):
            return 0.0, 0.0, True
        shrink = reach / math.sqrt(length_sq)
        u, w = u * shrink, w * shrink
    return u, w / ahead if ahead > 0.0 else omega0, True


@njit(inline="always", error_model="numpy")
def safety_filter(
    x: float, y: float, c: float, s: float, u0: float, omega0: float, params: FloatArray,
    i: int, positions: FloatArray, shapes: FloatArray, peer_lo: int, peer_hi: int, skip: int,
    obstacles: FloatArray, safety: tuple[float, float, float, float, float], dt: float,
) -> tuple[float, float, bool]:  # fmt: skip
    """(u, omega) closest to the nominal (u0, omega0) that keeps every body clear (module
    docstring), and whether it differs from the nominal. Heading cos c, sin s."""
    margin, ahead, rate, own_spread, own_heading = safety
    if dt > 0.0:
        rate = min(rate, 1.0 / dt)
    w0 = ahead * omega0
    # The result is never longer than the aim (the nominal plus the sideways aim below):
    # a body whose bound is beyond that cannot bind.
    reach = (1.0 + SIDE_STEP) * math.sqrt(u0 * u0 + w0 * w0)
    if reach <= 0.0:
        return u0, omega0, False
    r, b = params[i, WHEEL_RADIUS], params[i, HALF_AXLE]
    turn = reach / ahead if ahead > 0.0 else abs(omega0)
    if params[i, MAX_WHEEL_SPEED] < math.inf:
        turn = min(turn, r * params[i, MAX_WHEEL_SPEED] / b)
    eps = (ahead * turn * turn + reach * turn) * dt / rate if rate > 0.0 else 0.0
    px, py = x + ahead * c, y + ahead * s
    own = params[i, BODY_RADIUS] + ahead + margin + eps
    cons = np.empty((MAX_CONSTRAINTS, 3))
    n = 0
    stop = False
    half = 0.5 * rate
    binding, near_x, near_y = 0, 0.0, 0.0  # peers whose constraint is in; the last one
    # A peer whose centre is farther than this cannot bind (|p_j - p_i| is within 2 l of the
    # centres' distance; the slack keeps the cull from ever skipping one the test keeps).
    far = reach / half + own + 3.0 * ahead + own_spread + _CULL_SLACK
    for j in range(peer_lo, peer_hi):
        if j == skip:
            continue
        ex, ey = positions[0, j] - x, positions[1, j] - y
        reach_j = far + shapes[0, j] + shapes[1, j]
        if ex * ex + ey * ey >= reach_j * reach_j:
            continue
        th = positions[2, j]
        dx = positions[0, j] + ahead * math.cos(th) - px
        dy = positions[1, j] + ahead * math.sin(th) - py
        gap = math.sqrt(dx * dx + dy * dy) - own - shapes[0, j] - ahead
        spread = own_spread + shapes[1, j]
        before = n
        n, hold = _add_body(cons, n, dx, dy, c, s, gap, spread, own_heading, half, reach)
        stop |= hold
        if n != before:
            binding, near_x, near_y = binding + 1, ex, ey
    peer_rows = n
    along_wall = False  # a constraint of a wall the robot runs along is in
    segments = obstacles.shape[0] > END_Y
    for j in range(obstacles.shape[1]):
        dx, dy = obstacle_offset(obstacles, j, px, py)
        distance = math.sqrt(dx * dx + dy * dy)
        gap = distance - own - obstacles[3, j]
        before = n
        n, hold = _add_body(cons, n, dx, dy, c, s, gap, own_spread, own_heading, rate, reach)
        stop |= hold
        if n != before and segments and 2.0 * abs(c * dx + s * dy) <= distance:
            # a wall segment within 30 degrees of the heading (its closest point abeam)
            along_wall |= (
                obstacles[END_X, j] != obstacles[0, j] or obstacles[END_Y, j] != obstacles[1, j]
            )
    if stop or n < 0:
        return 0.0, 0.0, True
    if n == 0 or _satisfies(cons, n, u0, w0):
        return u0, omega0, False
    # Bound: aim to the side of the law's rotation sense (left for (17), right for (20)),
    # so that robots meeting head-on pass each other instead of stopping nose to nose.
    side = SIDE_STEP / (1.0 + SIDE_STEP) * reach
    right = params[i, CW] != 0.0
    if params[i, ON_VIA] != 0.0 and n == peer_rows and binding == 1:
        # On a via leg with one peer binding and nothing else: away from it, seen from the
        # straight way to the via-point; dead ahead, the law's side.
        ax, ay = params[i, GOAL_X] - x, params[i, GOAL_Y] - y
        across = ax * near_y - ay * near_x
        if abs(across) > SIDE_TIE_M * math.sqrt(ax * ax + ay * ay):
            right = across > 0.0
    if right:
        side = -side
    turn_cost = _turn_cost(b, ahead, n == peer_rows)
    u, w = u0, w0 + side
    capped = -1
    if along_wall:
        # Along a wall (not a post, not a wall ahead): turn at most HELD_TURN_RATE (or as
        # the nominal does) when a command that does not reverse allows it -- slow down
        # rather than turn faster than latency can follow (module docstring); else uncapped.
        cap = ahead * max(HELD_TURN_RATE, abs(omega0))
        capped = _add_half_plane(cons, _add_half_plane(cons, n, 0.0, 1.0, cap), 0.0, -1.0, cap)
    if capped > 0:
        u, w = closest_feasible(cons, capped, u, w, turn_cost)
        if u * u0 < 0.0 or not _satisfies(cons, capped, u, w):
            capped = -1
    if capped < 0:
        u, w = closest_feasible(cons, n, u0, w0 + side, turn_cost)
    u, omega, _ = _within_reach(cons, n, u, w, reach, ahead, omega0)
    return u, _held_turn(cons, n, u, omega, u0, omega0, ahead), True


#: [rad/s] the fastest a robot the filter holds turns beyond its nominal path's curvature.
HELD_TURN_RATE = 1.5


@njit(inline="always", error_model="numpy")
def _held_turn(
    cons: FloatArray, n: int, u: float, omega: float, u0: float, omega0: float, ahead: float
) -> float:
    """The filter's omega [rad/s] capped at the nominal path's curvature at the speed it
    keeps (|omega0| |u| / |u0|), or ``HELD_TURN_RATE``, whichever is more, moved no
    further towards the cap than the constraints allow at that u."""
    if ahead <= 0.0:
        return omega
    cap = HELD_TURN_RATE
    if u0 != 0.0:
        cap = max(cap, abs(omega0) * abs(u) / abs(u0))
    if abs(omega) <= cap:
        return omega
    lo, hi = -math.inf, math.inf
    for k in range(n):
        a1, a2, c = cons[k, 0], cons[k, 1], cons[k, 2]
        if a2 > 0.0:
            hi = min(hi, (c - a1 * u) / a2)
        elif a2 < 0.0:
            lo = max(lo, (c - a1 * u) / a2)
    target = math.copysign(cap * ahead, omega)
    return min(max(target, lo), hi) / ahead


# -- THE step ---------------------------------------------------------------------------------
# -- routes (scalar, compiled) ---------------------------------------------------------------
@njit(inline="always", error_model="numpy")
def _cross(ax: float, ay: float, bx: float, by: float, px: float, py: float) -> float:
    """(b - a) x (p - a): > 0 when p lies left of the line from a to b."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


@njit(inline="always", error_model="numpy")
def _segment_gap(
    px: float, py: float, qx: float, qy: float, ax: float, ay: float, bx: float, by: float
) -> float:
    """Distance [m] between the segments p-q and a-b (0 when they cross)."""
    d1, d2 = _cross(ax, ay, bx, by, px, py), _cross(ax, ay, bx, by, qx, qy)
    d3, d4 = _cross(px, py, qx, qy, ax, ay), _cross(px, py, qx, qy, bx, by)
    if d1 * d2 < 0.0 and d3 * d4 < 0.0:
        return 0.0
    best = math.inf
    for ox, oy, sx, sy, ex, ey in (
        (px, py, ax, ay, bx, by), (qx, qy, ax, ay, bx, by),
        (ax, ay, px, py, qx, qy), (bx, by, px, py, qx, qy),
    ):  # fmt: skip
        dx, dy = _closest_offset(sx, sy, ex, ey, ox, oy)
        best = min(best, math.sqrt(dx * dx + dy * dy))
    return best


@njit(inline="always", error_model="numpy")
def _sight_blocked(
    x0: float, y0: float, x1: float, y1: float, obstacles: FloatArray, clearance: float
) -> bool:
    """Whether a disc of radius ``clearance`` [m] moving straight from (x0, y0) to (x1, y1)
    would touch a static obstacle's body."""
    walls = obstacles.shape[0] > END_Y
    for j in range(obstacles.shape[1]):
        ax, ay = obstacles[0, j], obstacles[1, j]
        bx, by = (obstacles[END_X, j], obstacles[END_Y, j]) if walls else (ax, ay)
        if _segment_gap(x0, y0, x1, y1, ax, ay, bx, by) < obstacles[BODY, j] + clearance:
            return True
    return False


@njit(inline="always", error_model="numpy")
def _aim(
    x: float, y: float, theta: float, params: FloatArray, i: int, route: FloatArray, leg: int,
    obstacles: FloatArray,
) -> int:  # fmt: skip
    """:func:`aim` on row i of ``params``, inlined into the batch."""
    last, pass_sq = int(params[i, ROUTE_LAST]), params[i, PASS_SQ]
    while leg < last:
        dx, dy = route[VIA_X, leg] - x, route[VIA_Y, leg] - y
        d_sq = dx * dx + dy * dy
        if d_sq >= pass_sq:
            break
        if d_sq >= 0.25 * pass_sq and _sight_blocked(  # beyond half the pass radius
            x, y, route[VIA_X, leg + 1], route[VIA_Y, leg + 1], obstacles, params[i, BODY_RADIUS]
        ):
            break  # the next leg cuts a corner from here: drive on to the via-point
        leg += 1
    params[i, GOAL_X], params[i, GOAL_Y] = route[VIA_X, leg], route[VIA_Y, leg]
    params[i, ON_VIA] = 1.0 if leg < last else 0.0
    if leg < last:  # a via-point: face it, turning the shorter way (right: law (20))
        dx, dy = route[VIA_X, leg] - x, route[VIA_Y, leg] - y
        params[i, GOAL_HEADING] = wrap_to_2pi(math.atan2(dy, dx))
        params[i, CW] = 1.0 if math.cos(theta) * dy - math.sin(theta) * dx < 0.0 else 0.0
    else:
        params[i, GOAL_HEADING], params[i, CW] = route[VIA_HEADING, leg], route[VIA_CW, leg]
    return leg


@njit(
    "int64(float64, float64, float64, float64[:, ::1], float64[:, ::1], int64, float64[:, ::1])",
    cache=True,
    error_model="numpy",
)
def aim(
    x: float, y: float, theta: float, params: FloatArray, route: FloatArray, leg: int,
    obstacles: FloatArray,
) -> int:  # fmt: skip
    """Point robot ``params[0]`` at (x [m], y [m], theta [rad]) along its route table
    ``route``, from entry ``leg`` on; returns the entry it now aims at.

    It passes every via-point within the pass-through radius (``params[0, PASS_SQ]``) of
    (x, y) -- unless the straight way from (x, y) to the next entry would bring its body
    into a static obstacle's (``obstacles``, rows of the step; a corner cut short), then it
    drives on until it is within half that radius (closer still, peers crowding a gate's
    corner would keep it from ever passing). At a via-point it
    aims at the posture *facing* it (the bearing from the robot) with the law that turns
    the shorter way ((20) when it lies to the right, y_e < 0): the robot turns towards the
    via-point and drives on. Both laws command u = kx x_e, so the distance to the via-point
    never grows (the Lyapunov-like L = (x_e^2 + y_e^2) / 2 of Eq. (10.a),
    ``fleet.core.switching``) and the robot reaches it. Last comes the goal with the task's
    law. Writes the goal columns of ``params[0]`` and ``ON_VIA``; the agent calls it before
    its tick's step and the batch before each step (the same code: the planner predicts it).
    """
    return _aim(x, y, theta, params, 0, route, leg, obstacles)


class StepResult(NamedTuple):
    """One step of one robot: pre-step error, stop rule, applied control, next posture."""

    x_e: float  # [m] pre-step error, Eq. (5), robot frame
    y_e: float  # [m]
    theta_e: float  # [rad], law's wrap
    done: bool  # pre-step error within tolerance (the step is still applied)
    u: float  # [m/s] applied (after repulsion, saturation and the safety filter)
    omega: float  # [rad/s]
    right: float  # [rad/s] wheel speeds of (u, omega), Eq. (2)
    left: float
    repulsion: float  # [m/s] Eq. (27) sum added to u before saturation
    avoiding: bool  # a peer or obstacle is within its influence radius, or the filter acted
    x: float  # posture after the Euler step [m, m, rad]
    y: float
    theta: float


@njit(inline="always", error_model="numpy")
def robot_step(
    x: float,
    y: float,
    theta: float,
    nominal_x: float,
    nominal_y: float,
    nominal_theta: float,
    params: FloatArray,
    i: int,
    hold: bool,
    positions: FloatArray,
    shapes: FloatArray,
    peer_lo: int,
    peer_hi: int,
    skip: int,
    obstacles: FloatArray,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    safety: tuple[float, float, float, float, float],
    dt: float,
) -> tuple[float, float, float, bool, float, float, float, float, float, bool, float, float, float]:
    """One closed-loop step of robot ``params[i]`` at (x, y, theta) (see the module docstring).

    The law and Eq. (27) (steps 4-5) act on the pose (``nominal_x``, ``nominal_y``,
    ``nominal_theta``) -- the same pose, or the agent's prediction of its pose when its
    command acts (latency compensation: docs/safety.md) --; the error, the stop rule, the
    safety filter and the Euler step on (x, y, theta). Peers are columns
    ``peer_lo .. peer_hi - 1`` of ``positions`` (x, y, theta) and ``shapes`` (body radius,
    spread) except ``skip`` (the robot itself in a batch, -1 otherwise). Returns the fields
    of :class:`StepResult`.
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

    nx_, ny_, nc, ns = x, y, c, s
    xn_e, yn_e, thetan_e = x_e, y_e, theta_e
    if nominal_x != x or nominal_y != y or nominal_theta != theta:
        nx_, ny_ = nominal_x, nominal_y
        nc, ns = math.cos(nominal_theta), math.sin(nominal_theta)
        xn_e, yn_e, thetan_e = _error_in_frame(
            nc, ns, nx_, ny_, nominal_theta, params[i, GOAL_X], params[i, GOAL_Y],
            params[i, GOAL_HEADING], cw,
        )  # fmt: skip
    kx, ky, ktheta = params[i, KX], params[i, KY], params[i, KTHETA]
    u, omega = posture_law(xn_e, yn_e, thetan_e, kx, ky, ktheta, cw)
    repulsion = 0.0
    avoiding = False
    if k_avoid > 0.0:
        influence_sq = peer_radius * peer_radius
        smoothing = params[i, SMOOTHING]
        for j in range(peer_lo, peer_hi):
            if j == skip:
                continue
            dx, dy = positions[0, j] - nx_, positions[1, j] - ny_
            d_sq = dx * dx + dy * dy
            if d_sq < influence_sq:
                repulsion += repulsion_term(
                    nc * dx + ns * dy, d_sq, peer_radius, k_avoid, min_x_oa, smoothing
                )  # Eq. (26)
                avoiding = True
        for j in range(obstacles.shape[1]):
            dx, dy = obstacle_offset(obstacles, j, nx_, ny_)
            d_sq = dx * dx + dy * dy
            if d_sq < obstacles[2, j] * obstacles[2, j]:
                repulsion += repulsion_term(
                    nc * dx + ns * dy, d_sq, obstacles[2, j], k_avoid, min_x_oa, smoothing
                )
                avoiding = True
    max_wheel = params[i, MAX_WHEEL_SPEED]
    u, omega = saturate(u + repulsion, omega, r, b, max_wheel)
    if safety[0] >= 0.0:
        u, omega, filtered = safety_filter(
            x, y, c, s, u, omega, params, i, positions, shapes, peer_lo, peer_hi, skip,
            obstacles, safety, dt,
        )  # fmt: skip
        if filtered:
            u, omega = saturate(u, omega, r, b, max_wheel)
            avoiding = True
    right, left = wheel_speeds(u, omega, r, b)
    nx, ny, ntheta = _euler(x, y, theta, c, s, u, omega, dt)
    return x_e, y_e, theta_e, done, u, omega, right, left, repulsion, avoiding, nx, ny, ntheta


_STEP_RESULT = "Tuple((float64, float64, float64, boolean, float64, float64, float64, float64, float64, boolean, float64, float64, float64))"  # noqa: E501


@njit(
    _STEP_RESULT + "(float64, float64, float64, float64, float64, float64, float64[:, ::1], "
    "boolean, float64[:, ::1], "
    "float64[:, ::1], float64[:, ::1], float64, float64, float64, "
    "UniTuple(float64, 5), float64)",
    cache=True,
    error_model="numpy",
)
def _step_robot(
    x: float,
    y: float,
    theta: float,
    nominal_x: float,
    nominal_y: float,
    nominal_theta: float,
    params: FloatArray,
    hold: bool,
    peers: FloatArray,
    shapes: FloatArray,
    obstacles: FloatArray,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    safety: tuple[float, float, float, float, float],
    dt: float,
) -> tuple[float, float, float, bool, float, float, float, float, float, bool, float, float, float]:
    return robot_step(
        x, y, theta, nominal_x, nominal_y, nominal_theta, params, 0, hold, peers, shapes, 0,
        peers.shape[1], -1, obstacles, k_avoid, peer_radius, min_x_oa, safety, dt,
    )  # fmt: skip


def step_robot(
    pose: tuple[float, float, float],
    params: FloatArray,
    *,
    hold: bool = False,
    peers: FloatArray,
    shapes: FloatArray,
    obstacles: FloatArray,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    safety: Safety = SAFETY_OFF,
    dt: float = 0.0,
    nominal: tuple[float, float, float] | None = None,
) -> StepResult:
    """One step of one robot (the agent's tick): :func:`robot_step` on ``params``
    (1, ``ROBOT_COLUMNS``), the law and Eq. (27) on ``nominal`` (x, y, theta) when given
    (the agent's latency compensation), else on ``pose``.

    ``peers`` (3, M) = x, y, theta, ``shapes`` (2, M) = body radius, spread and
    ``obstacles`` (4, K) are C-contiguous float64 rows (see the module docstring). ``dt``
    [s] is the control period: the safety filter's step, and it moves the returned posture.
    """
    at = pose if nominal is None else nominal
    return StepResult(
        *_step_robot(
            float(pose[0]), float(pose[1]), float(pose[2]), float(at[0]), float(at[1]),
            float(at[2]), params, hold, peers, shapes,
            obstacles, k_avoid, peer_radius, min_x_oa,
            (float(safety[0]), float(safety[1]), float(safety[2]), float(safety[3]),
             float(safety[4])), dt,
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
    route_last: FloatArray | None = None,
    pass_radius: FloatArray | float = 0.0,
    smoothing: FloatArray | float = 0.0,
) -> FloatArray:
    """Parameter rows (N, ``ROBOT_COLUMNS``) from per-robot columns (N,) and goal/gains (N, 3).

    ``delay_end`` [s]: the batch holds robot i while t < delay_end[i] (None: never).
    ``route_last``: the column of robot i's goal in the batch's route table (None or -1: no
    route); ``pass_radius`` [m] its via-points' pass-through radius; ``smoothing`` [m] the
    width of its Eq. (27) bands (:func:`repulsion_term`; 0: the paper's term).
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
    params[:, ROUTE_LAST] = -1.0 if route_last is None else route_last
    params[:, PASS_SQ] = np.square(pass_radius)
    params[:, SMOOTHING] = smoothing
    params[:, ON_VIA] = 0.0
    return params


# -- N robots, many steps ---------------------------------------------------------------------
class Interaction(NamedTuple):
    """How the robots of a batch act on each other: within blocks of ``group`` consecutive
    robots, through Eq. (27) with K_avoid [m^2/s] inside ``peer_radius`` [m] (x_OA guard
    ``min_x_oa`` [m]) and the safety filter; Eq. (27) not at all unless K_avoid > 0 and
    ``peer_radius`` > 0. K_avoid and ``min_x_oa`` act on static obstacles too. ``safety``:
    the filter (:class:`Safety`; its ``spread`` is every peer's too), which acts on static
    bodies whenever it is on, and among the robots of a group when ``peer_radius`` > 0
    (0: independent robots)."""

    group: int
    k_avoid: float
    peer_radius: float
    min_x_oa: float
    safety: tuple[float, float, float, float, float] = SAFETY_OFF


@njit("boolean(int64, float64, float64, float64)", cache=True, error_model="numpy")
def interacting(group: int, k_avoid: float, peer_radius: float, margin: float) -> bool:
    """Whether the robots of a batch act on each other at all (see :class:`Interaction`)."""
    return group > 1 and peer_radius > 0.0 and (k_avoid > 0.0 or margin >= 0.0)


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
    shapes: FloatArray,
    peer_lo: int,
    peer_hi: int,
    k_avoid: float,
    peer_radius: float,
    min_x_oa: float,
    safety: tuple[float, float, float, float, float],
    dt: float,
    record: FloatArray,
    row: int,
    route: FloatArray,
    leg: np.ndarray,
) -> int:
    """Robot i's step ``step`` (time ``t`` = step dt [s]) from ``current`` into
    ``following`` (both (3, N)), with peers ``peer_lo .. peer_hi - 1``; returns 1 if the
    stop rule fired. ``row`` >= 0 records the step in that row of ``record``. A robot with
    a route (``leg[i]`` >= 0, its entry in ``route``) first passes the via-points it is
    within the pass-through radius of and aims at the next entry (:func:`aim`)."""
    x, y, theta = current[0, i], current[1, i], current[2, i]
    moving = done_step[i] < 0
    if not moving and row < 0:  # done: stands still (still a peer of the others)
        following[0, i], following[1, i], following[2, i] = x, y, theta
        return 0
    if moving and leg[i] >= 0:
        leg[i] = _aim(x, y, theta, params, i, route, leg[i], obstacles)
    hold = t < params[i, DELAY_END]
    r = robot_step(
        x, y, theta, x, y, theta, params, i, hold, current, shapes, peer_lo, peer_hi, i,
        obstacles, k_avoid, peer_radius, min_x_oa, safety, dt,
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


@njit(cache=True, nogil=True, error_model="numpy")
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
    route: FloatArray,
    leg: np.ndarray,
) -> int:
    """Robots ``lo .. hi - 1`` for up to ``max_steps`` steps from step ``first_step``;
    returns the steps taken until all of them were done (see :func:`advance_batch`).

    Once every robot of the chunk is done nothing in it changes any more, so it stops
    there -- unless recording, which goes on to the end of the call (standing rows)."""
    group, k_avoid, peer_radius, min_x_oa, safety = interaction
    dt, first_step, max_steps, record_every = schedule
    peers = interacting(group, k_avoid, peer_radius, safety[0])
    span = group if peers else max(hi - lo, 1)
    shapes = np.empty((2, pose.shape[1]))  # every peer's body radius and the spread
    for i in range(lo, hi):
        shapes[0, i], shapes[1, i] = params[i, BODY_RADIUS], safety[3]
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
                    shapes, base, peer_hi, k_avoid, peer_radius, min_x_oa, safety, dt,
                    record, row, route, leg,
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
    (
        pose,
        spare,
        params,
        done_step,
        metrics,
        obstacles,
        interaction,
        schedule,
        record,
        pairs,
        route,
        leg,
    ) = args
    # The threads get scalars and arrays only (parfors take no named tuples).
    group, k_avoid, peer_radius, min_x_oa, safety = interaction
    margin, ahead, rate, spread, heading = safety  # scalars: parfors take no tuples
    dt, first_step, max_steps, record_every = schedule
    chunks = (n + chunk - 1) // chunk
    taken = np.zeros(chunks, dtype=np.int64)
    for c in prange(chunks):
        taken[c] = advance_chunk(
            c * chunk, min(n, (c + 1) * chunk), pose, spare, params, done_step, metrics,
            obstacles,
            Interaction(
                group, k_avoid, peer_radius, min_x_oa, (margin, ahead, rate, spread, heading)
            ),
            Schedule(dt, first_step, max_steps, record_every), record, pairs, route, leg,
        )  # fmt: skip
    most = 0
    for c in range(chunks):
        most = max(most, taken[c])
    return most


def defer_parallel_kernel(build: Callable[[], None]) -> None:
    """From now on, large batches of this process take the parallel kernel only once it is
    built: the first one calls ``build``, which must build it off the calling thread
    (``fleet.core.simulate.warm_parallel_kernel`` on a thread of the caller's), and runs
    on one thread, as do the others until it is built. None of them waits for its
    compile, and a process without large batches never builds it."""
    _deferral[:] = [build]


def parallel_kernel() -> str:
    """The state of this process's parallel kernel: "ready", "cold" (not built yet) or
    "unusable: why" (no thread-safe threading layer, or its compile failed)."""
    if _parallel["ready"]:
        return "ready"
    return f"unusable: {_parallel['error']}" if _parallel["error"] else "cold"


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
    route: FloatArray | None = None,
    leg: npt.NDArray[np.int64] | None = None,
    parallel: bool | None = None,
) -> int:
    """Advance N robots as ``schedule`` says, stopping when every robot is done; returns the
    steps taken (until the last one was done).

    ``pose`` (3, N) is updated in place; robots read their peers' pre-step positions and
    interact (Eq. 27 and the safety filter) as ``interaction`` says. Per robot:
    ``done_step`` (-1 while moving, then the step the stop rule fired; a done robot stands
    still) and ``metrics`` (``EFFORT``, ``DISTANCE``) accumulate. ``record`` (rows, N,
    ``RECORD_COLUMNS``) takes every step k with k % record_every == 0 of this call, in
    order; ``min_pair_sq`` (blocks, group, group) the smallest pre-step squared separations.
    ``route`` (``ROUTE_ROWS``, M) holds every robot's route table and ``leg`` (N,) the
    entry each robot aims at (-1: no route; updated in place, with its goal columns).

    Robots are simulated in independent chunks (whole blocks when they interact or
    separations are tracked), each through all its steps; large batches spread the chunks
    over the threads, so no thread waits for another between steps: with ``parallel``
    None, building the parallel kernel at the first one (a minute on a fresh install) or,
    deferred (:func:`defer_parallel_kernel`), once it is built; True: always (building it
    first if need be); False: never.
    """
    n = pose.shape[1]
    record = np.zeros((0, n, RECORD_COLUMNS)) if record is None else record
    min_pair_sq = np.zeros((0, 0, 0)) if min_pair_sq is None else min_pair_sq
    route = np.zeros((ROUTE_ROWS, 0)) if route is None else route
    leg = np.full(n, -1, dtype=np.int64) if leg is None else leg
    group = interaction.group
    peers = interacting(group, interaction.k_avoid, interaction.peer_radius, interaction.safety[0])
    unit = group if peers or min_pair_sq.shape[0] > 0 else 1
    chunk = unit * max(1, CHUNK_ROBOTS // unit)
    spare = np.empty_like(pose)
    args = (pose, spare, params, done_step, metrics, obstacles, interaction, schedule, record,
            min_pair_sq, route, leg)  # fmt: skip
    large = n > chunk and n * (group if peers else 1) >= PARALLEL_MIN_WORK
    if parallel is None:  # built, or to be built now unless deferred or unusable
        parallel = bool(_parallel["ready"] or not (_deferral or _parallel["error"]))
    build = _deferral[0] if large and not parallel and _deferral else None
    if build is not None:
        _deferral[0] = None
        build()  # elsewhere, once
    if large and parallel:
        try:
            taken = int(_advance_chunks_in_parallel(chunk, n, *args))
        except ValueError as error:  # raised while compiling, before any step ran
            if "threading layer" not in str(error):
                raise
            _parallel["error"] = str(error)  # no OpenMP or TBB here: one thread it is
        else:
            _parallel["ready"] = True
            return taken
    return max(
        (int(advance_chunk(lo, min(n, lo + chunk), *args)) for lo in range(0, n, chunk)),
        default=0,
    )
