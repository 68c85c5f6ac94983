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

Control of an active task (:func:`decide`) is :func:`fleet.core.step.aim` (the via-point
of its route it aims at, or its goal) then one call of the compiled control step,
:func:`fleet.core.step.step_robot` -- the same code the batch simulator and the planner's
rollouts run: error of Eq. (5), stop rule, law (17) ``ccw`` or (20) ``cw``, the repulsion
-K_avoid/x_OA of Eq. (27) from every peer within the peer influence radius and every
static obstacle within its own radius (mode ``avoiding`` while any is inside), the
wheel-speed limit (scaled together, curvature kept), the safety filter (the command
closest to that which keeps every body ``contact_margin_m`` clear of every peer's and
obstacle's body, with the spreads of :class:`fleet.core.params.SafetyConfig`; mode
``avoiding`` when it acts) and Eq. (2) to wheel speeds. Arrival is the stop rule on the
pre-step error (x_e^2 + y_e^2 < position^2 and
|theta_e| < heading); as in the batch simulator, that tick's command is still applied
(``arrived`` with the last, small, wheel command) and the robot stops at the next tick.
Importing this module compiles the step (or loads it from numba's cache): never in a tick.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np

from fleet.core import step
from fleet.core.params import Avoidance, RobotProfile, SafetyConfig
from fleet.core.route import route_table
from fleet.core.types import FloatArray
from fleet.core.wire import CancelAssignment, Obstacle, ParkAssignment, RobotMode
from robot_agent.prediction import point_speed

#: Tolerance [s] on the end of a start delay (the batch simulator uses the same).
DELAY_EPS = 1e-6


class AgentTaskStatus(StrEnum):
    ACTIVE = "active"
    ARRIVED = "arrived"
    CANCELLED = "cancelled"


def route_of(assignment: ParkAssignment) -> FloatArray:
    """The assignment's route table of :mod:`fleet.core.step` (its via-points, then its
    goal with its law): the table the planner's batch runs for it."""
    return route_table(assignment.route, assignment.goal.as_tuple(), assignment.law == "cw")


@dataclass(frozen=True)
class AgentTask:
    """The robot's current (or last) assignment and how far it got: ``leg`` is the entry
    of its route table (:func:`route_of`) it aims at (the goal when it has no route)."""

    assignment: ParkAssignment
    status: AgentTaskStatus = AgentTaskStatus.ACTIVE
    applied_at: float = 0.0  # [s, agent clock] when this revision was applied
    route: FloatArray = field(default_factory=lambda: np.zeros((step.ROUTE_ROWS, 0)))
    leg: int = 0

    def __post_init__(self) -> None:
        if self.route.shape[1] == 0:  # built once per assignment, not per tick
            object.__setattr__(self, "route", route_of(self.assignment))

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
            # re-planned: new law, route, delay or hold, same status
            return AgentTask(message, task.status, applied_at=now)
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
    """The stop rule on the pre-step error of Eq. (5) with the law's wrap."""
    goal, tol = assignment.goal, assignment.tolerance
    x_e, y_e, theta_e = step.pose_error(
        float(pose[0]), float(pose[1]), float(pose[2]), goal.x, goal.y, goal.theta,
        assignment.law == "cw",
    )  # fmt: skip
    return bool(step.within_tolerance(x_e, y_e, theta_e, tol.position**2, tol.heading))


def obstacle_arrays(obstacles: Sequence[Obstacle]) -> FloatArray:
    """Static obstacles as the compiled step's rows (``OBSTACLE_ROWS``, K) [m]: start x, y,
    influence radius, body radius, end x, y (a post's end is its centre)."""
    rows = [(o.x, o.y, o.radius, o.body_radius, *o.far_end) for o in obstacles]
    array = np.array(rows, dtype=np.float64).reshape(-1, step.OBSTACLE_ROWS)
    return np.ascontiguousarray(array.T)


#: No peers: postures (3, 0) and shapes (2, 0).
NO_PEERS: tuple[FloatArray, FloatArray] = (np.zeros((3, 0)), np.zeros((2, 0)))


def filter_of(
    safety: SafetyConfig | None,
    speed: float = 0.0,
    own_spread: float | None = None,
    own_heading: float = 0.0,
) -> step.Safety:
    """The compiled step's filter parameters for ``safety`` (off when None or disabled):
    the robot's own spread [m] is ``own_spread`` (its prediction's), else that of its last
    commanded speed ``speed`` [m/s] (:meth:`SafetyConfig.own_spread`); ``own_heading``
    [rad] its heading's uncertainty."""
    if safety is None:
        return step.SAFETY_OFF
    spread = safety.own_spread(speed) if own_spread is None else own_spread
    return step.Safety(*safety.filter_terms(spread), own_heading)


def cap_speed_up(
    result: TickResult, limit: float, half_axle: float, safety: SafetyConfig
) -> TickResult:
    """``result`` with its command scaled down (u, omega and both wheels by one factor in
    [0, 1]: the path's curvature kept) so that its projected point's speed bound
    (:func:`robot_agent.prediction.point_speed`) is at most ``limit`` [m/s].

    The agent passes its last command's bound plus ``max_accel_m_s2`` times the control
    period: no command's point speeds up faster than that, which is what peers assume of
    it (docs/safety.md). Braking and turning are never limited. Scaling keeps the safety
    filter's guarantee: a command the filter allows, scaled by s in [0, 1], closes every
    gap by at most s times as much (when it opened one, it opens it by less but still
    does not close it), and its second-order terms shrink by s^2.
    """
    speed = point_speed(result.u, result.omega, half_axle, safety)
    if speed <= limit or not result.moving:
        return result
    scale = max(limit, 0.0) / speed
    return replace(
        result,
        u=result.u * scale,
        omega=result.omega * scale,
        right=result.right * scale,
        left=result.left * scale,
    )


def _step_params(task: AgentTask, profile: RobotProfile, limit: float) -> FloatArray:
    """The robot's parameter row of :mod:`fleet.core.step` (1, ``ROBOT_COLUMNS``), its goal
    and law yet to be aimed along its route (:func:`fleet.core.step.aim`)."""
    assignment = task.assignment
    goal, gains, tol = assignment.goal, assignment.gains, assignment.tolerance

    def column(value: float) -> FloatArray:
        return np.array([value])

    return step.robot_params(
        np.array([goal.as_tuple()]),
        np.array([gains.as_tuple()]),
        column(1.0 if assignment.law == "cw" else 0.0),
        column(tol.position),
        column(tol.heading),
        column(profile.wheel_radius),
        column(profile.half_axle),
        column(limit),
        column(profile.radius),
        route_last=column(task.route.shape[1] - 1),
        pass_radius=assignment.pass_m,
        smoothing=assignment.avoidance.smoothing_m,
    )


def decide(
    pose: Sequence[float],
    pose_age: float,
    task: AgentTask | None,
    peers: tuple[FloatArray, FloatArray],
    obstacles: FloatArray,
    profile: RobotProfile,
    avoidance: Avoidance,
    pose_stale_s: float,
    link_ok: bool = True,
    now: float = 0.0,
    safety: SafetyConfig | None = None,
    speed: float = 0.0,
    period: float = 0.0,
    own_spread: float | None = None,
    own_heading: float = 0.0,
    nominal_pose: Sequence[float] | None = None,
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
    peers : (postures (3, M), shapes (2, M))
        Every other robot's last posture (x, y, theta) and its body radius and spread [m]
        (:meth:`robot_agent.world.WorldView.peer_bodies`; never forgotten, even when silent).
    obstacles : (``OBSTACLE_ROWS``, K)
        Static posts and wall segments with their influence and body radii [m], from
        :func:`obstacle_arrays`.
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
    safety : SafetyConfig or None
        The safety filter (None or ``enabled=False``: off, the paper's model).
    speed : float
        The robot's last commanded forward speed [m/s]: its own spread without a
        prediction (:meth:`SafetyConfig.own_spread`, commands in flight as a reach).
    period : float
        Control period [s]: the filter's step.
    own_spread : float or None
        This robot's own spread [m] when ``pose`` is its prediction for the instant the
        command acts (:func:`robot_agent.prediction.predict_own`); None: ``speed``'s.
    own_heading : float
        Uncertainty [rad] of that pose's heading: the filter widens every cone by it.
    nominal_pose : (x [m], y [m], theta [rad]) or None
        Where the law, Eq. (27) and the route's next via-point are reckoned from: the
        robot's prediction of its pose when the command acts (latency compensation,
        ``SafetyConfig.compensate_latency``), while the stop rule and the safety filter keep
        ``pose`` and its spread; None: ``pose``.
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
    # The task's avoidance parameters win when the fleet sent them; else the robot's own.
    avoid = a.avoidance if "avoidance" in a.model_fields_set else avoidance
    limit = profile.max_wheel_speed
    if a.max_wheel_speed is not None:
        limit = min(limit, a.max_wheel_speed)  # never above the robot's own limit
    hold = task.waiting(now)
    params = _step_params(task, profile, limit)
    at = pose if nominal_pose is None else nominal_pose
    leg = step.aim(at[0], at[1], at[2], params, task.route, task.leg, obstacles)
    if leg != task.leg:
        task = replace(task, leg=leg)
    postures, shapes = peers
    result = step.step_robot(
        (pose[0], pose[1], pose[2]),
        params,
        hold=hold,
        peers=np.ascontiguousarray(postures, dtype=np.float64),
        shapes=np.ascontiguousarray(shapes, dtype=np.float64),
        obstacles=obstacles,
        k_avoid=avoid.k_avoid,
        peer_radius=avoid.peer_radius,
        min_x_oa=avoid.min_x_oa,
        safety=filter_of(safety, speed, own_spread, own_heading),
        dt=period,
        nominal=None if nominal_pose is None else (at[0], at[1], at[2]),
    )
    if result.done:  # the stop rule: this step is still applied (see the module docstring)
        mode, task = RobotMode.ARRIVED, replace(task, status=AgentTaskStatus.ARRIVED)
    elif hold:
        return _stopped(RobotMode.WAITING, task, "held by the fleet" if a.hold else "start delay")
    else:
        mode = RobotMode.AVOIDING if result.avoiding else RobotMode.DRIVING
    return TickResult(
        mode=mode,
        task=task,
        u=result.u,
        omega=result.omega,
        right=result.right,
        left=result.left,
        repulsion=result.repulsion,
    )
