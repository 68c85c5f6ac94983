"""Scalar reference of the closed loop: plain Python floats, the tests' oracle only.

The maths of the one compiled step (:mod:`fleet.core.step`) written again with the ``math``
module only, in the same order of operations: the posture error of Eq. (5) with the heading
wraps (11.a), (11.b) and (21), the stop rule, law (17) (``ccw``) or (20) (``cw``), the
Eq. (27) repulsion from peers and static obstacles with the x_OA guard, the wheel-speed
saturation of Eq. (2), the contact guard, and a forward-Euler step of the kinematics,
Eq. (3). Property tests hold the compiled step, the batch simulator, the agent and the
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
    """Eq. (27) and the contact guard: K_avoid [m^2/s], peer influence radius [m], x_OA
    guard [m] and the robot's body radius [m] (contact at 2 radius + min_x_oa)."""

    k_avoid: float
    peer_radius: float
    min_x_oa: float
    radius: float


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


def repulsion_term(x_oa: float, k_avoid: float, min_x_oa: float) -> float:
    """-K_avoid / x_OA of Eq. (27) with |x_OA| floored at ``min_x_oa`` keeping its sign."""
    guarded = max(x_oa, min_x_oa) if x_oa >= 0.0 else min(x_oa, -min_x_oa)
    return -k_avoid / guarded


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
    peers: Sequence[tuple[float, float]] = (),
    obstacles: Sequence[tuple[float, float, float]] = (),
    hold: bool = False,
) -> Step:
    """One closed-loop step of ``dt`` [s]: error (5), law (17)/(20), repulsion (27) from
    ``peers`` (x, y) within the peer radius and ``obstacles`` (x, y, radius) within their
    own radius, saturation, contact guard, Euler on (3). ``hold``: stand still."""
    x, y, theta = pose
    error = pose_error(pose, goal, cw)
    if hold:
        return Step(error=error, u=0.0, omega=0.0, pose=pose)
    u, omega = posture_law(error, gains, cw)
    repulsion = 0.0
    avoiding = close_ahead = close_behind = False
    if avoidance is not None and avoidance.k_avoid > 0.0:
        c, s = math.cos(theta), math.sin(theta)
        k, guard = avoidance.k_avoid, avoidance.min_x_oa
        contact = 2.0 * avoidance.radius + guard
        for px, py in peers:
            dx, dy = px - x, py - y
            d_sq = dx * dx + dy * dy
            x_oa = c * dx + s * dy  # Eq. (26)
            if d_sq < avoidance.peer_radius * avoidance.peer_radius:
                repulsion += repulsion_term(x_oa, k, guard)
                avoiding = True
            if d_sq < contact * contact:
                close_ahead = close_ahead or x_oa > 0.0
                close_behind = close_behind or x_oa < 0.0
        for ox, oy, radius in obstacles:
            dx, dy = ox - x, oy - y
            if dx * dx + dy * dy < radius * radius:
                repulsion += repulsion_term(c * dx + s * dy, k, guard)
                avoiding = True
    u += repulsion
    if limit is not None:
        u, omega = saturate(u, omega, limit)
    if (u > 0.0 and close_ahead) or (u < 0.0 and close_behind):
        u = 0.0  # contact guard
        avoiding = True
    new_pose = (x + math.cos(theta) * u * dt, y + math.sin(theta) * u * dt, theta + omega * dt)
    return Step(error, u, omega, new_pose, repulsion, avoiding)


def simulate_loop(
    starts: Sequence[Posture],
    goals: Sequence[Posture],
    gains: Sequence[GainTriple],
    laws: Sequence[Law],
    *,
    avoidance: Avoidance | None = None,
    obstacles: Sequence[tuple[float, float, float]] = (),
    start_delay: Sequence[float] | None = None,
    tol_position: float = 0.05,
    tol_heading: float = 0.02,
    dt: float = 0.01,
    max_time: float = 60.0,
    limit: WheelLimit | None = None,
) -> list[RobotRun]:
    """Simulate N robots step by step until each is done or ``max_time`` [s] has passed.

    With ``avoidance`` every robot is a peer of every other (Eq. 27 and the contact guard)
    and static ``obstacles`` (x, y, radius) repel; without it the robots are independent.
    Each step reads the others' pre-step positions. A robot is done at the first step k
    whose pre-step error satisfies x_e^2 + y_e^2 < ``tol_position``^2 [m] and
    |theta_e| < ``tol_heading`` [rad]; that step is still applied (time (k + 1) dt), then
    it stands still. It also stands still while t < its start delay [s] (minus 1e-6 s, as
    the batch simulator). Tolerances, ``dt`` and the wheel limit are shared.
    """
    if not len(starts) == len(goals) == len(gains) == len(laws):
        raise ValueError("starts, goals, gains and laws must have the same length")
    n = len(starts)
    delays = [-math.inf] * n if start_delay is None else [d - 1e-6 for d in start_delay]
    poses = list(starts)
    done_at: list[int | None] = [None] * n
    effort, distance = [0.0] * n, [0.0] * n
    steps = round(max_time / dt)
    for k in range(steps):
        if all(d is not None for d in done_at):
            break
        following = list(poses)
        for i in range(n):
            if done_at[i] is not None:
                continue
            peers = [(p[0], p[1]) for j, p in enumerate(poses) if j != i] if avoidance else []
            result = step(
                poses[i], goals[i], gains[i], laws[i] == "cw", dt, limit,
                avoidance=avoidance, peers=peers, obstacles=obstacles, hold=k * dt < delays[i],
            )  # fmt: skip
            distance[i] += abs(result.u) * dt
            effort[i] += (abs(result.omega) + abs(result.u)) * dt  # Eq. (25)
            following[i] = result.pose
            if within_tolerance(result.error, tol_position, tol_heading):
                done_at[i] = k
        poses = following
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
