"""Scalar reference of the closed loop: one robot, one step, plain Python floats.

The same maths as :mod:`fleet.core.control` and :func:`fleet.core.simulate.simulate` without
obstacles, written with the ``math`` module only: the posture error of Eq. (5) with the
heading wraps (11.a), (11.b) and (21), law (17) (``ccw``) or (20) (``cw``), the optional
wheel-speed saturation of Eq. (2), and a forward-Euler step of the kinematics, Eq. (3).

It serves two purposes: property tests check the vectorised simulator against it, and
``parkfleet bench sim`` uses :func:`simulate_loop` as the plain per-robot Python loop that
the batch simulator is compared with. Keep it straightforward, not clever.
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


class Step(NamedTuple):
    """One closed-loop step: pre-step error, applied control and the posture after it."""

    error: Posture  # (x_e [m], y_e [m], theta_e [rad]) before the step, Eq. (5)
    u: float  # [m/s]
    omega: float  # [rad/s]
    pose: Posture  # after the Euler update


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
) -> Step:
    """One closed-loop step of ``dt`` [s]: error (5), law (17)/(20), saturation, Euler on (3)."""
    error = pose_error(pose, goal, cw)
    u, omega = posture_law(error, gains, cw)
    if limit is not None:
        u, omega = saturate(u, omega, limit)
    x, y, theta = pose
    new_pose = (x + math.cos(theta) * u * dt, y + math.sin(theta) * u * dt, theta + omega * dt)
    return Step(error=error, u=u, omega=omega, pose=new_pose)


def simulate_robot(
    start: Posture,
    goal: Posture,
    gains: GainTriple,
    law: Law,
    *,
    tol_position: float,
    tol_heading: float,
    dt: float,
    max_steps: int,
    limit: WheelLimit | None = None,
) -> RobotRun:
    """Run one robot until the stop rule fires or ``max_steps`` steps have been applied.

    The robot is done at the first step k whose pre-step error satisfies
    hypot(x_e, y_e) < ``tol_position`` [m] and |theta_e| < ``tol_heading`` [rad]; that step
    is still applied, so its time is (k + 1) dt.
    """
    cw = law == "cw"
    pose = start
    effort = distance = 0.0
    for k in range(max_steps):
        result = step(pose, goal, gains, cw, dt, limit)
        x_e, y_e, theta_e = result.error
        distance += abs(result.u) * dt
        effort += (abs(result.omega) + abs(result.u)) * dt  # Eq. (25)
        pose = result.pose
        if math.hypot(x_e, y_e) < tol_position and abs(theta_e) < tol_heading:
            return RobotRun(True, (k + 1) * dt, effort, distance, pose, k + 1)
    return RobotRun(False, math.nan, effort, distance, pose, max_steps)


def simulate_loop(
    starts: Sequence[Posture],
    goals: Sequence[Posture],
    gains: Sequence[GainTriple],
    laws: Sequence[Law],
    *,
    tol_position: float = 0.05,
    tol_heading: float = 0.02,
    dt: float = 0.01,
    max_time: float = 60.0,
    limit: WheelLimit | None = None,
) -> list[RobotRun]:
    """Simulate N robots one after the other, each with :func:`simulate_robot`.

    Per-robot sequences must have equal lengths; tolerances [m, rad], ``dt`` [s],
    ``max_time`` [s] and the wheel limit are shared, as in a uniform fleet.
    """
    if not len(starts) == len(goals) == len(gains) == len(laws):
        raise ValueError("starts, goals, gains and laws must have the same length")
    max_steps = round(max_time / dt)
    return [
        simulate_robot(
            s,
            g,
            k,
            law,
            tol_position=tol_position,
            tol_heading=tol_heading,
            dt=dt,
            max_steps=max_steps,
            limit=limit,
        )
        for s, g, k, law in zip(starts, goals, gains, laws, strict=True)
    ]
