"""The closed loop every baseline runs in: the paper's unicycle, forward Euler, stop rule.

The same loop as the batch simulator of laws (17)/(20) (:mod:`fleet.core.simulate`), for
controllers that are not the paper's: kinematics of Eq. (3) integrated by forward Euler at
``dt`` (0.01 s in the paper); a robot is done at the first step k whose *pre-step* error is
within tolerance (||(x_e, y_e)|| < position and |theta_e| < heading, theta_e = theta_r -
theta_c wrapped to (-pi, pi]); that step is still applied, so its time is (k + 1) dt;
afterwards it stands still. Metrics: control effort of Eq. (25), int(|u| + |omega|) dt;
distance int |u| dt; time. An optional wheel limit scales (u, omega) together
(:func:`fleet.core.step.saturate`), as the robots do.

A controller is a :class:`Policy` made for one batch of start/goal postures (it may keep
state between steps, e.g. VFO's continuous angle or FT's phase clock): called with the
poses (N, 3) and the time t [s], it returns (u [m/s], omega [rad/s]), each (N,).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np
import numpy.typing as npt

from fleet.core.params import UNLIMITED, RobotProfile, Tolerance
from fleet.core.simulate import PAPER_DT, SimResult, Trajectory
from fleet.core.step import saturate
from fleet.core.types import FloatArray

Policy = Callable[[FloatArray, float], tuple[FloatArray, FloatArray]]


class Controller(Protocol):
    """A baseline: a name, its source, and a policy factory for start/goal batches."""

    @property
    def name(self) -> str: ...

    def policy(self, start: FloatArray, goal: FloatArray) -> Policy:
        """A fresh policy for robots starting at ``start`` (N, 3) bound for ``goal`` (N, 3)."""
        ...


def wrap_to_pi(angle: npt.ArrayLike) -> FloatArray:
    """Angle(s) mapped to (-pi, pi] [rad]."""
    a = np.asarray(angle, dtype=np.float64)
    wrapped = np.pi - np.mod(np.pi - a, 2.0 * np.pi)
    return np.asarray(wrapped, dtype=np.float64)


def body_error(pose: FloatArray, goal: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(x_e, y_e, theta_e): the goal in the robot frame, Eq. (5), theta_e in (-pi, pi]."""
    dx, dy = goal[:, 0] - pose[:, 0], goal[:, 1] - pose[:, 1]
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    return c * dx + s * dy, c * dy - s * dx, wrap_to_pi(goal[:, 2] - pose[:, 2])


def closed_loop(
    controller: Controller,
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    tolerance: Tolerance,
    dt: float = PAPER_DT,
    max_time: float = 60.0,
    profile: RobotProfile = UNLIMITED,
    record: bool = False,
) -> SimResult:
    """Run ``controller`` from ``start`` to ``goal`` (each (3,) or (N, 3)) until every robot
    is done or ``max_time`` [s] passes; the result has the simulator's shape and units."""
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError("dt must be a positive finite number of seconds")
    s = np.atleast_2d(np.asarray(start, dtype=np.float64)).copy()
    g = np.broadcast_to(np.atleast_2d(np.asarray(goal, dtype=np.float64)), s.shape).copy()
    if s.shape[1] != 3 or not (np.isfinite(s).all() and np.isfinite(g).all()):
        raise ValueError("start and goal must be finite postures (x, y, theta)")
    n = s.shape[0]
    policy = controller.policy(s.copy(), g.copy())
    pose = s
    active = np.ones(n, dtype=bool)
    done_step = np.full(n, -1, dtype=np.int64)
    effort, distance = np.zeros(n), np.zeros(n)
    poses: list[FloatArray] = []
    controls: list[FloatArray] = []
    errors: list[FloatArray] = []
    limited = math.isfinite(profile.max_wheel_speed)
    steps = round(max_time / dt)
    step = 0
    while step < steps and active.any():
        x_e, y_e, theta_e = body_error(pose, g)
        finished = active & (np.hypot(x_e, y_e) < tolerance.position)
        finished &= np.abs(theta_e) < tolerance.heading
        done_step[finished] = step
        u, omega = policy(pose.copy(), step * dt)
        u, omega = np.where(active, u, 0.0), np.where(active, omega, 0.0)
        if not (np.isfinite(u).all() and np.isfinite(omega).all()):
            raise ArithmeticError(f"{controller.name} gave a non-finite control at step {step}")
        if limited:  # the robots' own saturation, robot by robot
            for i in range(n):
                u[i], omega[i] = saturate(
                    u[i], omega[i], profile.wheel_radius, profile.half_axle, profile.max_wheel_speed
                )
        if record:
            poses.append(pose.copy())
            controls.append(np.stack([u, omega], axis=1))
            errors.append(np.stack([x_e, y_e, theta_e], axis=1))
        effort += (np.abs(u) + np.abs(omega)) * dt  # Eq. (25)
        distance += np.abs(u) * dt
        theta = pose[:, 2]
        pose = np.stack(
            [
                pose[:, 0] + np.cos(theta) * u * dt,
                pose[:, 1] + np.sin(theta) * u * dt,
                theta + omega * dt,
            ],
            axis=1,
        )
        active &= ~finished
        step += 1
    done = done_step >= 0
    trajectory = None
    if record:
        poses.append(pose.copy())
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
        final_pose=pose,
        steps=step,
        trajectory=trajectory,
    )
