"""Pure per-tick decision logic of a robot agent (no Zenoh, no clock, no I/O).

One tick: given the robot's own pose (and its age), its task, its peers' last positions
and the static obstacles, decide the wheel command and the mode to report. The agent
(:mod:`robot_agent.agent`) feeds it from Zenoh and the drive; tests feed it directly.

Task protocol (``fleet.core.wire`` module docstring), as a pure state machine
(:func:`apply_assignment`):

* a ``ParkAssignment`` with a new ``task_id`` replaces the current task; a repeat of the
  current ``task_id`` with the same or a lower ``revision`` is ignored (delivery is
  at-least-once, stale revisions may arrive late);
* a higher ``revision`` of the current ``task_id`` (the fleet re-planned it) replaces the
  assignment -- law, gains, tolerance, limits -- and keeps the task's status: an active task
  drives on from where it is with the new law, an arrived or cancelled one stays so;
* ``hold``, or the ``start_delay_s`` after the assignment (or revision) was applied ->
  stand still, ``waiting``, task active (the time comes from the agent's clock, ``now``);
* a ``CancelAssignment`` for the current task -> ``holding`` with the task id kept;
  a cancel for any other task is ignored;
* arrival within tolerance -> stop, ``arrived`` (latched until a new task);
* no task -> stand still, ``idle``;
* own pose stale or link to the fleet network lost -> stop, ``holding``, task kept (still
  active: it resumes when the pose or the link comes back).

Every stop says why (``TickResult.detail``: ``pose stale``, ``link lost``, ``task
cancelled``, ``start delay``, ``held by the fleet``). An operator's pause or e-stop
(:mod:`robot_agent.operator`) overrides the whole tick in the agent, before :func:`decide`.

Control of an active task (:func:`decide`): error of Eq. (5), law (17) ``ccw`` or (20)
``cw``, plus the repulsion -K_avoid/x_OA of Eq. (27) from every peer within the peer
influence radius and every static obstacle within its own radius (mode ``avoiding``
while any is inside), then the wheel-speed limit (scaled together, curvature kept), a
contact guard (no forward motion towards a peer within two body radii plus the x_OA
guard; see :func:`_towards_contact`) and Eq. (2) to wheel speeds. Arrival uses the batch
simulator's stop rule: the pre-step error is within tolerance (||(x_e, y_e)|| < position
and |theta_e| < heading).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np

from fleet.core.control import is_cw, obstacle_repulsion, pose_error, posture_law, saturate
from fleet.core.control import wheel_speeds as to_wheel_speeds
from fleet.core.params import Avoidance, RobotProfile
from fleet.core.types import FloatArray
from fleet.core.wire import CancelAssignment, Obstacle, ParkAssignment, RobotMode

#: Tolerance [s] on the end of a start delay (the batch simulator uses the same).
DELAY_EPS = 1e-6


class AgentTaskStatus(StrEnum):
    ACTIVE = "active"
    ARRIVED = "arrived"
    CANCELLED = "cancelled"


@dataclass(frozen=True)
class AgentTask:
    """The robot's current (or last) assignment and how far it got."""

    assignment: ParkAssignment
    status: AgentTaskStatus = AgentTaskStatus.ACTIVE
    applied_at: float = 0.0  # [s, agent clock] when this revision was applied

    @property
    def task_id(self) -> str:
        return self.assignment.task_id

    def waiting(self, now: float) -> bool:
        """Whether the robot must stand still at ``now`` [s]: held, or in its start delay.

        The delay ends at the first tick at or after ``applied_at + start_delay_s``, within
        ``DELAY_EPS`` (ticks are sums of periods: exact times are off by rounding).
        """
        a = self.assignment
        return a.hold or now < self.applied_at + a.start_delay_s - DELAY_EPS


def apply_assignment(
    task: AgentTask | None, message: ParkAssignment | CancelAssignment, now: float = 0.0
) -> AgentTask | None:
    """Next task after an assignment message received at ``now`` [s, agent clock] (see the
    module docstring for the rules)."""
    if isinstance(message, ParkAssignment):
        if task is not None and task.task_id == message.task_id:
            if message.revision <= task.assignment.revision:
                return task  # at-least-once delivery: a repeat or a stale revision is ignored
            # re-planned: new law, delay or hold, same status
            return replace(task, assignment=message, applied_at=now)
        return AgentTask(message, applied_at=now)
    if task is not None and task.task_id == message.task_id:
        return replace(task, status=AgentTaskStatus.CANCELLED)
    return task


@dataclass(frozen=True)
class TickResult:
    """Output of one tick: body and wheel command, mode to report, task after the tick."""

    mode: RobotMode
    task: AgentTask | None
    u: float = 0.0  # forward speed [m/s]
    omega: float = 0.0  # turn rate [rad/s]
    right: float = 0.0  # right wheel [rad/s]
    left: float = 0.0  # left wheel [rad/s]
    repulsion: float = 0.0  # Eq. (27) sum added to u before saturation [m/s]
    detail: str | None = None  # why the robot stands still (RobotState.detail)

    @property
    def moving(self) -> bool:
        return self.right != 0.0 or self.left != 0.0


def _stopped(mode: RobotMode, task: AgentTask | None, detail: str | None = None) -> TickResult:
    return TickResult(mode=mode, task=task, detail=detail)


def within_tolerance(pose: Sequence[float] | FloatArray, assignment: ParkAssignment) -> bool:
    """The simulator's stop rule on the pre-step error of Eq. (5) with the law's wrap."""
    x_e, y_e, theta_e = pose_error(pose, assignment.goal.as_tuple(), is_cw(assignment.law))
    return bool(
        math.hypot(float(x_e), float(y_e)) < assignment.tolerance.position
        and abs(float(theta_e)) < assignment.tolerance.heading
    )


def obstacle_arrays(obstacles: Sequence[Obstacle]) -> tuple[FloatArray, FloatArray]:
    """Static obstacles as centres (M, 2) [m] and influence radii (M,) [m]."""
    if not obstacles:
        return np.zeros((0, 2)), np.zeros(0)
    centres = np.array([(o.x, o.y) for o in obstacles], dtype=np.float64)
    radii = np.array([o.radius for o in obstacles], dtype=np.float64)
    return centres, radii


def _towards_contact(
    p: FloatArray, peers: FloatArray, u: float, profile: RobotProfile, avoid: Avoidance
) -> bool:
    """Whether driving at speed ``u`` moves towards a peer already within contact range.

    Contact guard (not in the paper; on whenever avoidance is, i.e. k_avoid > 0): Eq. (27)
    slows a robot near a peer but does not forbid contact -- a robot whose goal lies
    behind a standing (e.g. dead) peer settles where the law's pull and the repulsion
    balance, which with the default gains is closer than two body radii. Within
    ``2 * radius + min_x_oa`` of a peer centre the robot may turn on the spot or move
    away, never towards it.
    """
    contact = 2.0 * profile.radius + avoid.min_x_oa
    dx = peers[:, 0] - p[0]
    dy = peers[:, 1] - p[1]
    near = dx * dx + dy * dy < contact * contact
    if not bool(near.any()):
        return False
    ahead = math.cos(p[2]) * dx[near] + math.sin(p[2]) * dy[near]  # x_OA of each close peer
    return bool((ahead > 0).any()) if u > 0 else bool((ahead < 0).any())


def decide(
    pose: Sequence[float],
    pose_age: float,
    task: AgentTask | None,
    peers: FloatArray,
    obstacles: tuple[FloatArray, FloatArray],
    profile: RobotProfile,
    avoidance: Avoidance,
    pose_stale_s: float,
    link_ok: bool = True,
    now: float = 0.0,
) -> TickResult:
    """Decide one control tick.

    Parameters
    ----------
    pose : (x [m], y [m], theta [rad])
        Own posture in the world frame, as last measured.
    pose_age : float
        Age of that measurement [s]; above ``pose_stale_s`` the robot is stopped
        (``holding``) while it has an active task.
    task : AgentTask or None
        Current task (see :func:`apply_assignment`).
    peers : ndarray, shape (M, 2)
        Last known centres [m] of every other robot (never forgotten, even when silent).
    obstacles : (centres (K, 2), radii (K,))
        Static obstacles and their influence radii [m], from :func:`obstacle_arrays`.
    profile : RobotProfile
        Wheel radius, half axle and wheel-speed limit of this robot.
    avoidance : Avoidance
        The robot's own K_avoid, peer influence radius and x_OA guard (from
        ``Settings.avoidance``); an assignment that sets ``avoidance`` explicitly wins.
    pose_stale_s : float
        Maximum pose age [s] before the robot holds.
    link_ok : bool
        Whether the robot still hears the fleet's Zenoh network
        (:class:`robot_agent.link.LinkMonitor`); without it the robot cannot see its
        peers, so an active task holds (``holding``) until the link returns.
    now : float
        Agent clock [s]: a held task, or one within its start delay, waits (``waiting``).
    """
    if task is None:
        return _stopped(RobotMode.IDLE, None)
    if task.status is AgentTaskStatus.ARRIVED:
        return _stopped(RobotMode.ARRIVED, task)
    if task.status is AgentTaskStatus.CANCELLED:
        return _stopped(RobotMode.HOLDING, task, "task cancelled")
    if not pose_age <= pose_stale_s:  # also catches NaN
        return _stopped(RobotMode.HOLDING, task, "pose stale")
    if not link_ok:  # blind to its peers: stop, keep the task, resume when the link returns
        return _stopped(RobotMode.HOLDING, task, "link lost")

    a = task.assignment
    p = np.asarray(pose, dtype=np.float64)
    if within_tolerance(p, a):
        return _stopped(RobotMode.ARRIVED, replace(task, status=AgentTaskStatus.ARRIVED))
    if task.waiting(now):
        return _stopped(RobotMode.WAITING, task, "held by the fleet" if a.hold else "start delay")

    cw = is_cw(a.law)
    x_e, y_e, theta_e = pose_error(p, a.goal.as_tuple(), cw)
    u, omega = posture_law(x_e, y_e, theta_e, a.gains.as_tuple(), cw)  # Eq. (17) / (20)

    # The task's avoidance parameters win when the fleet sent them; else the robot's own.
    avoid = a.avoidance if "avoidance" in a.model_fields_set else avoidance
    repulsion = 0.0
    active = False
    if avoid.k_avoid > 0:
        centres, radii = obstacles
        for points, radius in ((peers, avoid.peer_radius), (centres, radii)):
            if points.shape[0] == 0:
                continue
            d2 = (points[:, 0] - p[0]) ** 2 + (points[:, 1] - p[1]) ** 2
            if bool((d2 < np.asarray(radius) ** 2).any()):
                active = True
                repulsion += float(
                    obstacle_repulsion(p, points, radius, avoid.k_avoid, avoid.min_x_oa)
                )  # Eq. (27)

    limit = profile.max_wheel_speed
    if a.max_wheel_speed is not None:
        limit = min(limit, a.max_wheel_speed)  # never above the robot's own limit
    u_s, w_s = saturate(float(u) + repulsion, omega, profile.wheel_radius, profile.half_axle, limit)
    if (
        avoid.k_avoid > 0  # part of avoidance: k_avoid = 0 switches both off
        and peers.shape[0]
        and float(u_s) != 0.0
        and _towards_contact(p, peers, float(u_s), profile, avoid)
    ):
        u_s = u_s * 0.0  # contact guard: turn on the spot, never drive into a peer
        active = True
    right, left = to_wheel_speeds(u_s, w_s, profile.wheel_radius, profile.half_axle)
    return TickResult(
        mode=RobotMode.AVOIDING if active else RobotMode.DRIVING,
        task=task,
        u=float(u_s),
        omega=float(w_s),
        right=float(right),
        left=float(left),
        repulsion=repulsion,
    )
