"""Scalar reference of the closed loop: plain Python floats, the tests' oracle only.

The maths of the one compiled step (:mod:`fleet.core.step`) written again with the ``math``
module only, in the same order of operations: the posture error of Eq. (5) with the heading
wraps (11.a), (11.b) and (21), the stop rule, law (17) (``ccw``) or (20) (``cw``), the
Eq. (27) repulsion from peers and static obstacles with the x_OA guard, the wheel-speed
saturation of Eq. (2), the safety filter (the closest command to the nominal that keeps
every body clear), and a forward-Euler step of the kinematics, Eq. (3). With
``latency_steps`` the loop also models command latency: a robot decides on its own pose
predicted through its commands in flight, sees its peers as they are now with a spread
that covers the motion they may make meanwhile, and its command acts that many steps
later. Property tests hold the compiled step, the batch simulator, the agent and the
simulated drive to it. Keep it straightforward, not clever (and out of production code).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

from fleet.core.types import GainTriple, Law, Posture

TWO_PI = math.tau


@dataclass(frozen=True)
class WheelLimit:
    """Wheel geometry and limit of Eq. (2): radius r [m], half axle b [m], max speed [rad/s]."""

    wheel_radius: float
    half_axle: float
    max_wheel_speed: float


@dataclass(frozen=True)
class Avoidance:
    """Eq. (27): K_avoid [m^2/s], peer influence radius [m], x_OA guard [m]; the robot's
    body radius [m] (the safety filter's); the width [m] of the term's smoothed bands
    (0: the paper's term)."""

    k_avoid: float
    peer_radius: float
    min_x_oa: float
    radius: float
    smoothing: float = 0.0


@dataclass(frozen=True)
class Safety:
    """The safety filter (``fleet.core.step.Safety``): margin [m] between bodies, projection
    l [m], barrier rate [1/s], own spread [m], own heading uncertainty [rad]."""

    margin: float
    projection: float
    rate: float
    spread: float = 0.0
    heading: float = 0.0


@dataclass(frozen=True)
class Body:
    """Another robot as the filter sees it: pose (x, y, theta), body radius and spread [m]."""

    x: float
    y: float
    theta: float
    radius: float
    spread: float = 0.0


#: A static obstacle: (x, y, influence radius, body radius) for a post, plus (end x, end y)
#: for a wall segment from (x, y) to the end [m].
ObstacleRow = tuple[float, ...]


def obstacle_offset(obstacle: ObstacleRow, px: float, py: float) -> tuple[float, float]:
    """(dx, dy) [m] from (px, py) to the closest point of the obstacle's post or segment."""
    ax, ay = obstacle[0], obstacle[1]
    if len(obstacle) < 6:
        return ax - px, ay - py
    ex, ey = obstacle[4] - ax, obstacle[5] - ay
    length_sq = ex * ex + ey * ey
    t = 0.0
    if length_sq > 0.0:
        t = min(max(((px - ax) * ex + (py - ay) * ey) / length_sq, 0.0), 1.0)
    return ax + t * ex - px, ay + t * ey - py


SIDE_STEP = 0.5
TURN_PRICE = 0.5
HELD_TURN_RATE = 1.5  # [rad/s]
SIDE_TIE_M = 0.05  # [m]
MAX_CONSTRAINTS = 48  # half-planes the compiled step holds (its cap rows need two)
_SQRT_HALF = math.sqrt(0.5)
_TOL = 1e-12


def _body_half_planes(
    dx: float, dy: float, c: float, s: float, gap: float, spread: float, heading: float,
    share_rate: float, reach: float,
) -> list[tuple[float, float, float]] | None:  # fmt: skip
    """The half-planes (a1, a2, bound) in (u, l omega) that keep one body clear, [] when
    they cannot bind, None when only a standstill is safe; the cone of directions within
    ``spread`` [m] of the body is widened by the own ``heading`` uncertainty [rad]."""
    bound = share_rate * (gap - spread)
    if bound >= reach:
        return []
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
        if bound <= 0.0:
            return None
        inner = bound * _SQRT_HALF
        return [(1.0, 0.0, inner), (-1.0, 0.0, inner), (0.0, 1.0, inner), (0.0, -1.0, inner)]
    mx, my = dx / distance, dy / distance
    a1, a2 = c * mx + s * my, c * my - s * mx
    if heading <= 0.0:
        if spread <= 0.0:
            return [(a1, a2, bound)]
        sin_phi = spread / distance
        cos_phi = math.sqrt(1.0 - sin_phi * sin_phi)
    planes = [
        (a1 * cos_phi - a2 * sin_phi, a2 * cos_phi + a1 * sin_phi, bound),
        (a1 * cos_phi + a2 * sin_phi, a2 * cos_phi - a1 * sin_phi, bound),
    ]
    if bound > 0.0:
        planes.append((a1, a2, bound * cos_phi))
    return planes


def _satisfies(planes: Sequence[tuple[float, float, float]], u: float, w: float) -> bool:
    return all(a1 * u + a2 * w <= bound + _TOL for a1, a2, bound in planes)


def closest_feasible(
    planes: Sequence[tuple[float, float, float]], u0: float, w0: float, turn_cost: float
) -> tuple[float, float]:
    """The point of the half-planes' intersection closest to (u0, w0) in the metric
    du^2 + ``turn_cost`` dw^2, else (0, 0)."""
    if _satisfies(planes, u0, w0):
        return u0, w0
    best, best_u, best_w = math.inf, 0.0, 0.0
    for a1, a2, bound in planes:
        excess = a1 * u0 + a2 * w0 - bound
        if excess > 0.0:
            b2 = a2 / turn_cost
            t = excess / (a1 * a1 + a2 * b2)
            cu, cw = u0 - t * a1, w0 - t * b2
            d = (cu - u0) * (cu - u0) + turn_cost * ((cw - w0) * (cw - w0))
            if d < best and _satisfies(planes, cu, cw):
                best, best_u, best_w = d, cu, cw
    for k, (a1, a2, c1) in enumerate(planes):
        for b1, b2, c2 in planes[k + 1 :]:
            det = a1 * b2 - a2 * b1
            if abs(det) < 1e-12:
                continue
            cu, cw = (c1 * b2 - a2 * c2) / det, (a1 * c2 - c1 * b1) / det
            d = (cu - u0) * (cu - u0) + turn_cost * ((cw - w0) * (cw - w0))
            if d < best and _satisfies(planes, cu, cw):
                best, best_u, best_w = d, cu, cw
    return best_u, best_w


def safety_filter(
    pose: Posture,
    u0: float,
    omega0: float,
    *,
    cw: bool,
    radius: float,
    limit: WheelLimit | None,
    peers: Sequence[Body],
    obstacles: Sequence[ObstacleRow],
    safety: Safety,
    dt: float,
    via: tuple[float, float] | None = None,
) -> tuple[float, float, bool]:
    """(u, omega) closest to the nominal that keeps every body clear, and whether it acted
    (the maths of ``fleet.core.step.safety_filter``; ``obstacles`` as in :func:`step`;
    ``via``: the via-point (x, y) [m] the robot aims at, None on its goal's leg)."""
    x, y, theta = pose
    c, s = math.cos(theta), math.sin(theta)
    ahead, rate = safety.projection, safety.rate
    if dt > 0.0:
        rate = min(rate, 1.0 / dt)
    w0 = ahead * omega0
    # The result is never longer than the aim (the nominal plus the sideways aim below):
    # a body whose bound is beyond that cannot bind.
    reach = (1.0 + SIDE_STEP) * math.sqrt(u0 * u0 + w0 * w0)
    if reach <= 0.0:
        return u0, omega0, False
    turn = reach / ahead if ahead > 0.0 else abs(omega0)
    if limit is not None and limit.max_wheel_speed < math.inf:
        turn = min(turn, limit.wheel_radius * limit.max_wheel_speed / limit.half_axle)
    eps = (ahead * turn * turn + reach * turn) * dt / rate if rate > 0.0 else 0.0
    px, py = x + ahead * c, y + ahead * s
    own = radius + ahead + safety.margin + eps
    planes: list[tuple[float, float, float]] = []
    stop = False
    binding: list[Body] = []  # peers whose constraint is in
    for peer in peers:
        dx = peer.x + ahead * math.cos(peer.theta) - px
        dy = peer.y + ahead * math.sin(peer.theta) - py
        gap = math.sqrt(dx * dx + dy * dy) - own - peer.radius - ahead
        spread = safety.spread + peer.spread
        more = _body_half_planes(dx, dy, c, s, gap, spread, safety.heading, 0.5 * rate, reach)
        stop = stop or more is None
        planes += more or []
        if more:
            binding.append(peer)
    peer_rows = len(planes)
    along_wall = False  # a constraint of a wall the robot runs along (within 30 deg) is in
    for obstacle in obstacles:
        dx, dy = obstacle_offset(obstacle, px, py)
        distance = math.sqrt(dx * dx + dy * dy)
        gap = distance - own - obstacle[3]
        more = _body_half_planes(dx, dy, c, s, gap, safety.spread, safety.heading, rate, reach)
        stop = stop or more is None
        planes += more or []
        if more and len(obstacle) > 5 and 2.0 * abs(c * dx + s * dy) <= distance:
            along_wall = along_wall or obstacle[4:6] != obstacle[0:2]
    if stop:
        return 0.0, 0.0, True
    if not planes or _satisfies(planes, u0, w0):
        return u0, omega0, False
    side = SIDE_STEP / (1.0 + SIDE_STEP) * reach
    right = cw
    if via is not None and len(planes) == peer_rows and len(binding) == 1:
        # On a via leg with one peer binding and nothing else: away from it, seen from the
        # straight way to the via-point; dead ahead, the law's side.
        ax, ay = via[0] - x, via[1] - y
        across = ax * (binding[0].y - y) - ay * (binding[0].x - x)
        if abs(across) > SIDE_TIE_M * math.sqrt(ax * ax + ay * ay):
            right = across > 0.0
    if right:
        side = -side
    # Among peers only, a change of w = l omega costs (TURN_PRICE b / l)^2 beside u's
    # (at least 1); with a static body in range, 1 (turn along it).
    turn_cost = 1.0
    if len(planes) == peer_rows and ahead > 0.0:
        k = TURN_PRICE * (limit.half_axle if limit is not None else ahead) / ahead
        turn_cost = max(k * k, 1.0)
    u, w = u0, w0 + side
    capped = False
    if along_wall and len(planes) + 2 <= MAX_CONSTRAINTS:
        # Along a wall (not a post, not a wall ahead): turn at most HELD_TURN_RATE (or as the
        # nominal does) when a command that does not reverse allows it; else uncapped.
        cap = ahead * max(HELD_TURN_RATE, abs(omega0))
        rows = [*planes, (0.0, 1.0, cap), (0.0, -1.0, cap)]
        u, w = closest_feasible(rows, u, w, turn_cost)
        capped = u * u0 >= 0.0 and _satisfies(rows, u, w)
    if not capped:
        u, w = closest_feasible(planes, u0, w0 + side, turn_cost)
    length_sq = u * u + w * w
    if length_sq > reach * reach:  # shortened to reach: towards 0 if 0 is feasible
        if not _satisfies(planes, 0.0, 0.0):
            return 0.0, 0.0, True
        shrink = reach / math.sqrt(length_sq)
        u, w = u * shrink, w * shrink
    if ahead <= 0.0:
        return u, omega0, True
    # The turn capped at the nominal path's curvature at the kept speed, or HELD_TURN_RATE,
    # moved towards the cap no further than the half-planes allow at this u.
    cap = HELD_TURN_RATE
    if u0 != 0.0:
        cap = max(cap, abs(omega0) * abs(u) / abs(u0))
    omega = w / ahead
    if abs(omega) <= cap:
        return u, omega, True
    lo, hi = -math.inf, math.inf
    for a1, a2, bound in planes:
        if a2 > 0.0:
            hi = min(hi, (bound - a1 * u) / a2)
        elif a2 < 0.0:
            lo = max(lo, (bound - a1 * u) / a2)
    return u, min(max(math.copysign(cap * ahead, omega), lo), hi) / ahead, True


class Step(NamedTuple):
    """One closed-loop step: pre-step error, applied control and the posture after it."""

    error: Posture  # (x_e [m], y_e [m], theta_e [rad]) before the step, Eq. (5)
    u: float  # [m/s]
    omega: float  # [rad/s]
    pose: Posture  # after the Euler update
    repulsion: float = 0.0  # [m/s] Eq. (27) sum added to u before saturation
    avoiding: bool = False  # something within its influence radius, or the guard acted


@dataclass(frozen=True)
class RobotRun:
    """Outcome of one robot's run: metrics of Eq. (25), distance int |u| dt and time."""

    done: bool
    time: float  # [s]; NaN if the tolerance was not reached
    control_effort: float
    distance: float  # [m]
    final_pose: Posture
    steps: int  # steps applied to this robot


def wrap_to_2pi(theta: float) -> float:
    """Orientation mapped to [0, 2pi), Eq. (11.a); same guard as ``control.wrap_to_2pi``."""
    wrapped = theta % TWO_PI  # Python's float % has numpy.mod's sign convention
    return 0.0 if wrapped >= TWO_PI else wrapped


def heading_error(theta_goal: float, theta: float, cw: bool) -> float:
    """Heading error theta_e [rad] of Eq. (5): (11.a) then (11.b) for ccw, (21) for cw.

    Mirrors :func:`fleet.core.control.heading_error`, including the guards that map a
    difference rounded onto +-2pi back to 0.
    """
    diff = wrap_to_2pi(theta_goal) - wrap_to_2pi(theta)
    ccw_err = diff + TWO_PI if diff < 0.0 else diff  # (11.b)
    if ccw_err >= TWO_PI:
        ccw_err = 0.0
    if cw and ccw_err > 0.0:
        cw_err = ccw_err - TWO_PI  # (21)
        return 0.0 if cw_err <= -TWO_PI else cw_err
    return ccw_err


def pose_error(pose: Posture, goal: Posture, cw: bool) -> Posture:
    """Posture error (x_e [m], y_e [m], theta_e [rad]): the goal in the robot frame, Eq. (5)."""
    x, y, theta = pose
    dx, dy = goal[0] - x, goal[1] - y
    c, s = math.cos(theta), math.sin(theta)
    return c * dx + s * dy, c * dy - s * dx, heading_error(goal[2], theta, cw)


def posture_law(error: Posture, gains: GainTriple, cw: bool) -> tuple[float, float]:
    """Law (17) (``cw`` False) or (20) (``cw`` True): (u [m/s], omega [rad/s]).

    u = kx x_e and omega = +-(ky y_e^2 + ktheta theta_e^2) e^(-|theta_e|).
    """
    x_e, y_e, theta_e = error
    kx, ky, ktheta = gains
    magnitude = (ky * (y_e * y_e) + ktheta * (theta_e * theta_e)) * math.exp(-abs(theta_e))
    return kx * x_e, -magnitude if cw else magnitude


def repulsion_term(
    x_oa: float, offset: tuple[float, float], influence: float, a: Avoidance
) -> float:
    """Eq. (27)'s term of a core at ``offset`` (dx, dy) [m] within ``influence`` [m].

    Without ``a.smoothing``: -K_avoid / x_OA with |x_OA| floored at the guard keeping its
    sign. With it (w [m]): linear in x_OA below g = max(w, guard), then scaled by how deep
    the core is in the outer w of the radius (from 0 at the edge to 1).
    """
    w = a.smoothing
    if w <= 0.0:
        guarded = max(x_oa, a.min_x_oa) if x_oa >= 0.0 else min(x_oa, -a.min_x_oa)
        return -a.k_avoid / guarded
    g = max(w, a.min_x_oa)
    dx, dy = offset
    depth = (influence - math.sqrt(dx * dx + dy * dy)) / w
    if abs(x_oa) < g:
        return min(1.0, depth) * (-a.k_avoid * x_oa / (g * g))
    return min(1.0, depth) * (-a.k_avoid / x_oa)


def within_tolerance(error: Posture, tol_position: float, tol_heading: float) -> bool:
    """The stop rule: x_e^2 + y_e^2 < tol_position^2 and |theta_e| < tol_heading."""
    x_e, y_e, theta_e = error
    return x_e * x_e + y_e * y_e < tol_position * tol_position and abs(theta_e) < tol_heading


def saturate(u: float, omega: float, limit: WheelLimit) -> tuple[float, float]:
    """Scale (u, omega) down together so neither wheel of Eq. (2) exceeds the limit.

    Same rule as :func:`fleet.core.control.saturate`: the curvature omega/u is kept.
    """
    r, b = limit.wheel_radius, limit.half_axle
    peak = max(abs((u + b * omega) / r), abs((u - b * omega) / r))
    if peak > limit.max_wheel_speed:
        scale = limit.max_wheel_speed / max(peak, 1e-300)
        return u * scale, omega * scale
    return u, omega


def step(
    pose: Posture,
    goal: Posture,
    gains: GainTriple,
    cw: bool,
    dt: float,
    limit: WheelLimit | None = None,
    *,
    avoidance: Avoidance | None = None,
    peers: Sequence[Body] = (),
    obstacles: Sequence[ObstacleRow] = (),
    hold: bool = False,
    safety: Safety | None = None,
    on_via: bool = False,
) -> Step:
    """One closed-loop step of ``dt`` [s]: error (5), law (17)/(20), repulsion (27) from
    ``peers`` within the peer radius and ``obstacles`` (x, y, influence radius, body
    radius[, end x, end y]: a post, or a wall segment from (x, y) to the end) within their
    influence radius, saturation, the safety filter (``safety``),
    saturation again, Euler on (3). ``hold``: stand still. ``on_via``: ``goal`` is a
    via-point the robot faces (the filter's side, :func:`safety_filter`)."""
    x, y, theta = pose
    error = pose_error(pose, goal, cw)
    if hold:
        return Step(error=error, u=0.0, omega=0.0, pose=pose)
    u, omega = posture_law(error, gains, cw)
    repulsion = 0.0
    avoiding = False
    c, s = math.cos(theta), math.sin(theta)
    if avoidance is not None and avoidance.k_avoid > 0.0:
        for peer in peers:
            dx, dy = peer.x - x, peer.y - y
            if dx * dx + dy * dy < avoidance.peer_radius * avoidance.peer_radius:
                x_oa = c * dx + s * dy  # Eq. (26)
                repulsion += repulsion_term(x_oa, (dx, dy), avoidance.peer_radius, avoidance)
                avoiding = True
        for obstacle in obstacles:
            dx, dy = obstacle_offset(obstacle, x, y)
            radius = obstacle[2]
            if dx * dx + dy * dy < radius * radius:
                repulsion += repulsion_term(c * dx + s * dy, (dx, dy), radius, avoidance)
                avoiding = True
    u += repulsion
    if limit is not None:
        u, omega = saturate(u, omega, limit)
    if safety is not None and safety.margin >= 0.0:
        u, omega, acted = safety_filter(
            pose, u, omega, cw=cw, radius=avoidance.radius if avoidance else 0.0, limit=limit,
            peers=peers, obstacles=obstacles, safety=safety,
            dt=dt, via=(goal[0], goal[1]) if on_via else None,
        )  # fmt: skip
        if acted:
            if limit is not None:
                u, omega = saturate(u, omega, limit)
            avoiding = True
    new_pose = (x + c * u * dt, y + s * u * dt, theta + omega * dt)
    return Step(error, u, omega, new_pose, repulsion, avoiding)


def predict(pose: Posture, commands: Sequence[tuple[float, float]], dt: float) -> Posture:
    """``pose`` after the Euler steps of ``commands`` (u, omega) in flight, in order."""
    x, y, theta = pose
    for u, omega in commands:
        x, y, theta = x + math.cos(theta) * u * dt, y + math.sin(theta) * u * dt, theta + omega * dt
    return x, y, theta


def simulate_loop(
    starts: Sequence[Posture],
    goals: Sequence[Posture],
    gains: Sequence[GainTriple],
    laws: Sequence[Law],
    *,
    avoidance: Avoidance | None = None,
    obstacles: Sequence[ObstacleRow] = (),
    start_delay: Sequence[float] | None = None,
    tol_position: float = 0.05,
    tol_heading: float = 0.02,
    dt: float = 0.01,
    max_time: float = 60.0,
    limit: WheelLimit | None = None,
    safety: Safety | None = None,
    latency_steps: int = 0,
    clearances: list[float] | None = None,
) -> list[RobotRun]:
    """Simulate N robots step by step until each is done or ``max_time`` [s] has passed.

    With ``avoidance`` every robot is a peer of every other (Eq. 27 and, with ``safety``,
    the filter) and static ``obstacles`` (rows as in :func:`step`) act;
    without it the robots are independent. A robot is done at the first step k whose
    pre-step error satisfies x_e^2 + y_e^2 < ``tol_position``^2 [m] and |theta_e| <
    ``tol_heading`` [rad]; that step is still applied (time (k + 1) dt), then it stands
    still. It also stands still while t < its start delay [s] (minus 1e-6 s, as the batch
    simulator). Tolerances, ``dt`` and the wheel limit are shared.

    ``latency_steps`` L: a command acts L steps after it was decided. Each robot decides on
    its own pose predicted through its L commands in flight, and sees every peer where it
    is now with a spread of the filter's own spread plus L dt times the peer's top speed
    (``limit``: the wheel speed times the wheel radius, which bounds the projected point's
    speed when the projection is at most the half axle); a done robot's commands in flight
    still act. ``clearances`` (if given) receives, after every step, the smallest body
    clearance [m] of any pair (centre distance - both radii) and of any robot to an
    obstacle's body.
    """
    if not len(starts) == len(goals) == len(gains) == len(laws):
        raise ValueError("starts, goals, gains and laws must have the same length")
    if latency_steps < 0:
        raise ValueError("latency_steps must be >= 0")
    n = len(starts)
    delays = [-math.inf] * n if start_delay is None else [d - 1e-6 for d in start_delay]
    radius = avoidance.radius if avoidance else 0.0
    top_speed = math.inf if limit is None else limit.wheel_radius * limit.max_wheel_speed
    spread = top_speed * latency_steps * dt if latency_steps else 0.0
    if safety is not None:
        spread += safety.spread  # as the batch: every robot's own spread is its peers' too
    poses = list(starts)
    in_flight: list[list[tuple[float, float]]] = [[(0.0, 0.0)] * latency_steps for _ in range(n)]
    done_at: list[int | None] = [None] * n
    effort, distance = [0.0] * n, [0.0] * n
    steps = round(max_time / dt)
    for k in range(steps):
        if all(d is not None for d in done_at) and all(
            all(c == (0.0, 0.0) for c in queue) for queue in in_flight
        ):
            break
        following = list(poses)
        for i in range(n):
            decided = (0.0, 0.0)
            if done_at[i] is None:
                peers = (
                    [Body(*p, radius, spread) for j, p in enumerate(poses) if j != i]
                    if avoidance
                    else []
                )
                result = step(
                    predict(poses[i], in_flight[i], dt), goals[i], gains[i], laws[i] == "cw",
                    dt, limit, avoidance=avoidance, peers=peers, obstacles=obstacles,
                    hold=k * dt < delays[i], safety=safety,
                )  # fmt: skip
                decided = (result.u, result.omega)
                if within_tolerance(result.error, tol_position, tol_heading):
                    done_at[i] = k
            queue = in_flight[i]
            queue.append(decided)
            u, omega = queue.pop(0)
            distance[i] += abs(u) * dt
            effort[i] += (abs(omega) + abs(u)) * dt  # Eq. (25)
            x, y, theta = poses[i]
            following[i] = (
                x + math.cos(theta) * u * dt,
                y + math.sin(theta) * u * dt,
                theta + omega * dt,
            )
        poses = following
        if clearances is not None:
            clearances.append(_smallest_clearance(poses, radius, obstacles))
    return [
        RobotRun(
            d is not None,
            (d + 1) * dt if d is not None else math.nan,
            effort[i],
            distance[i],
            poses[i],
            d + 1 if d is not None else steps,
        )
        for i, d in enumerate(done_at)
    ]


def _smallest_clearance(
    poses: Sequence[Posture], radius: float, obstacles: Sequence[ObstacleRow]
) -> float:
    """Smallest body clearance [m] between two robots or a robot and an obstacle's body."""
    smallest = math.inf
    for i, a in enumerate(poses):
        for b in poses[i + 1 :]:
            smallest = min(smallest, math.hypot(a[0] - b[0], a[1] - b[1]) - 2.0 * radius)
        for obstacle in obstacles:
            dx, dy = obstacle_offset(obstacle, a[0], a[1])
            smallest = min(smallest, math.hypot(dx, dy) - radius - obstacle[3])
    return smallest
