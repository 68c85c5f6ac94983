"""Independent peers: navground's ORCA, HRVO, HL and social-force behaviours on a scenario.

navground (https://idsia-robotics.github.io/navground, C++ core, on the package index)
computes the commands; the robots are the benchmark's own, the very ones parkfleet's agents
drive (:class:`PeerRobots`, in practice ``sim_agent.robots.SimRobots`` handed in by the CLI:
this layer imports no simulator). Each tick, in lockstep like ``parkfleet sim``: the link
delivers the peer states due (disturbed link: 20-200 ms late, 5 % lost), every robot reads
its *measured* pose from its drive (pose noise), its behaviour decides on that pose and on
the peers' states it has received, and the command goes to the drive as wheel speeds
(command latency, wheel noise and bias, the compiled step's Euler update); then the state
(measured pose, commanded velocity) is sent to the peers. With perfect robots every peer
sees every other's pose of the same tick. Robots and link come from one seed, the same as
the fleet's run of the scenario, so robot k has the same wheel bias under every policy.

The behaviours run on navground's core API (``Behavior.compute_cmd``), not navground's
simulated world: two-wheel differential-drive kinematics with the profile's wheel limit
(``max_speed`` = wheel radius x max wheel speed, the rim speed [m/s]; ``wheel_axis`` = 2 x
half axle), no reversing (navground's default), the same body radius, the agents' control
period as time step, the fleet's safety separation (navground's ``safety_margin`` =
separation - 2 x radius, added once to a pair's distance; social force ignores it), the
scenario's pose targets and tolerances (``Target.Pose``: these behaviours steer to a
*position*, then turn in place to the goal heading; the target is checked on the measured
pose) and its time limit. A behaviour's own velocity is the one it last commanded (as
navground's ``actuate`` keeps it: the robots have no velocity sensor). Tasks arrive at their
``arrival_s``; an unnamed scenario's goals go to idle robots by an optimal assignment on
straight-line distance (scipy's Hungarian method), one arrival group at a time. Around
walls and posts a robot gets the fleet's route (:mod:`fleet.core.planner.roadmap`, the
fleet's clearance): its via-points as point targets, each passed within the fleet's
pass-through radius, then the pose target (navground's local behaviours do not find a
gate on their own).

Ticks come out as :class:`~fleet.io.trace.TraceChunk` of *true* poses -- the same form as a
``parkfleet sim`` trace -- so :class:`~fleet.bench.metrics.RunMetrics` measures both alike.
Every robot sees peers and static obstacles (discs of the scenario's body radius) within
:data:`VIEW_RANGE_M` (a range beyond the yard made HRVO and social force 2-3x slower on the
car park's posts). On perfect robots the start poses get a seeded noise of the size of the
disturbed robots' pose noise (HL freezes in a perfectly symmetric ring). navground's values
are float32.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from fleet.bench.scenarios import Scenario
from fleet.core.params import RobotProfile
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.lanes import route_graph
from fleet.core.route import lane_shapes
from fleet.core.types import FloatArray, Posture
from fleet.core.wire import Obstacle, Pose, RobotMode
from fleet.io.trace import TraceChunk

#: Policy name -> navground behaviour type.
BEHAVIOURS: dict[str, str] = {
    "orca": "ORCA",
    "hrvo": "HRVO",
    "hl": "HL",
    "socialforce": "SocialForce",
}
#: Mode names of the ticks (the fleet's, so the metrics read both alike).
MODES: tuple[str, ...] = tuple(m.value for m in RobotMode)
_IDLE = MODES.index(RobotMode.IDLE.value)
_DRIVING = MODES.index(RobotMode.DRIVING.value)
_ARRIVED = MODES.index(RobotMode.ARRIVED.value)
#: Start-pose noise: std of x, y [m] and theta [rad].
START_NOISE = (0.01, math.radians(0.5))
#: Range [m] of every agent's view of peers and obstacles (a lidar's; 5 s ahead at 2 m/s closing).
VIEW_RANGE_M = 10.0


@dataclass(frozen=True)
class PeerRun:
    """What a peer run needs besides the scenario."""

    behaviour: str
    profile: RobotProfile
    safety_separation_m: float = 0.5
    #: [m] the fleet's contact margin: the peers' routes keep the fleet's clearance
    contact_margin_m: float = 0.05
    dt: float = 0.02
    seed: int = 0
    chunk_ticks: int = 500
    robots: PeerRobots | None = None


def assign_goals(scenario: Scenario) -> list[int]:
    """Robot index of each task: named -> itself; else per arrival group, an optimal
    assignment of the group's goals to the robots still idle, on straight-line distance."""
    n = len(scenario.robots)
    if scenario.named:
        return list(range(n))
    owner = [-1] * n
    free = list(range(n))
    starts = np.array([r.start[:2] for r in scenario.robots])
    for arrival in sorted({r.arrival_s for r in scenario.robots}):
        tasks = [k for k, r in enumerate(scenario.robots) if r.arrival_s == arrival]
        goals = np.array([scenario.robots[k].goal[:2] for k in tasks])
        cost = np.hypot(*(starts[free][:, None, :] - goals[None, :, :]).transpose(2, 0, 1))
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows, cols, strict=True):
            owner[tasks[c]] = free[r]
        taken = {free[r] for r in rows}
        free = [k for k in free if k not in taken]
    return owner


def goals_by_robot(scenario: Scenario, owner: list[int]) -> FloatArray:
    """(N, 3) goal of each robot (NaN rows for robots without a task)."""
    goals = np.full((len(scenario.robots), 3), np.nan)
    for task, robot in enumerate(owner):
        if robot >= 0:
            goals[robot] = scenario.robots[task].goal
    return goals


class PeerDrive(Protocol):
    """What a peer needs of a robot's drive (``sim_agent``'s drives are these)."""

    @property
    def true_pose(self) -> tuple[float, float, float]: ...

    def read_pose(self) -> tuple[Pose, float]: ...

    def command_wheels(self, right_rad_s: float, left_rad_s: float) -> None: ...

    def stop(self) -> None: ...


class PeerLink(Protocol):
    """Robot-to-robot delivery of peer states (``sim_agent.disturbances.DelayedLink``)."""

    def send(self, sender: int, message: Any, now: float) -> None: ...

    def deliver(self, now: float) -> list[tuple[int, Any]]: ...


class PeerClock(Protocol):
    """Simulated time [s] of the robots."""

    def now(self) -> float: ...

    def advance(self, seconds: float) -> float: ...


class PeerRobotSet(Protocol):
    """Built robots: clock, drives in robot order, link (``None``: every state at once)."""

    @property
    def clock(self) -> PeerClock: ...

    @property
    def drives(self) -> Sequence[PeerDrive]: ...

    @property
    def link(self) -> PeerLink | None: ...


class PeerRobots(Protocol):
    """How the benchmark's robots are built (``sim_agent.robots.SimRobots``)."""

    @property
    def disturbed(self) -> bool: ...

    def build(
        self,
        starts: Sequence[tuple[float, float, float]],
        profile: RobotProfile,
        seed: int | None,
        period: float,
    ) -> PeerRobotSet: ...


@dataclass(frozen=True)
class _PeerState:
    """What one robot tells the others: its measured position [m] and commanded velocity
    [m/s] (world frame), numbered."""

    sender: int
    seq: int
    x: float
    y: float
    vx: float
    vy: float


def _wheels(u: float, omega: float, profile: RobotProfile) -> tuple[float, float]:
    """Right and left wheel speeds [rad/s] of (u [m/s], omega [rad/s]) by Eq. (2), both
    scaled down together to the wheel limit (curvature kept; navground's float32 can
    exceed it by a hair)."""
    r, b, limit = profile.wheel_radius, profile.half_axle, profile.max_wheel_speed
    right, left = (u + b * omega) / r, (u - b * omega) / r
    scale = max(abs(right), abs(left)) / limit
    return (right / scale, left / scale) if scale > 1.0 else (right, left)


def _navground_obstacles(
    scenario: Scenario, core: ModuleType
) -> tuple[list[Any], list[tuple[Any, Obstacle]]]:
    """The scenario's posts as navground discs, and each wall segment as its outline: the
    two sides (line segments ``body`` to either side) and a disc at each end -- the same
    capsule the fleet's filter keeps clear of (navground's lines have no thickness). A
    wall is also a chain of discs of its body, ``body`` apart along it: navground's HRVO
    reads discs only (with the lines alone it drives through walls)."""
    discs: list[Any] = []  # navground.core.Disc
    lines: list[tuple[Any, Obstacle]] = []  # navground.core.LineSegment
    for o in scenario.static_obstacles():
        body = max(o.body_radius, 0.01)
        (ax, ay), (bx, by) = (o.x, o.y), o.far_end
        length = math.hypot(bx - ax, by - ay)
        discs.append(core.Disc((ax, ay), body))
        if length == 0.0:
            continue
        steps = math.ceil(length / body)
        discs.extend(
            core.Disc((ax + (bx - ax) * k / steps, ay + (by - ay) * k / steps), body)
            for k in range(1, steps + 1)
        )
        nx, ny = -(by - ay) / length * body, (bx - ax) / length * body
        for side in (1.0, -1.0):
            segment = core.LineSegment(
                (ax + side * nx, ay + side * ny), (bx + side * nx, by + side * ny)
            )
            lines.append((segment, o))
    return discs, lines


Router = Callable[[tuple[float, float], Posture], tuple[tuple[float, float], ...]]


def _router(scenario: Scenario, profile: RobotProfile, contact_margin_m: float) -> Router:
    """The fleet's routes for these robots: the via-points round the scenario's walls and
    posts from a position to a goal (:mod:`fleet.core.planner.roadmap`, the fleet's
    clearance), () where the way is straight or there is none."""
    obstacles = tuple(scenario.static_obstacles())
    config = PlannerConfig()
    if not obstacles:
        return lambda start, goal: ()
    clearance = config.route_clearance(profile.radius, contact_margin_m)
    roadmap = route_graph(obstacles, clearance, lane_shapes(scenario.lanes))
    return lambda start, goal: roadmap.route(start, goal, config.approach_m) or ()


def _next_target(
    core: ModuleType, via: Sequence[tuple[float, float]], goal: Any, pass_m: float
) -> Any:
    """The next via-point as a point target (passed within ``pass_m`` [m]), else the goal."""
    return core.Target.Point(via[0], pass_m) if via else goal


def run_peer(scenario: Scenario, run: PeerRun) -> Iterator[TraceChunk]:
    """Run ``scenario`` with a navground behaviour on ``run.robots``; yields its ticks until
    every task is done or the time limit (:attr:`Scenario.end_s`) passes. Raises
    ValueError for an unknown behaviour or without robots, and ImportError (with the fix)
    without navground."""
    if run.behaviour not in BEHAVIOURS:
        raise ValueError(
            f"unknown navground behaviour {run.behaviour!r}; one of {list(BEHAVIOURS)}"
        )
    if run.robots is None:
        raise ValueError("a peer run needs robots (sim_agent.robots.SimRobots, from the CLI)")
    try:
        from navground import core
    except ImportError as exc:  # an optional dependency of the benchmark
        raise ImportError(
            "the navground peers need navground: pip install 'parkfleet[test]' (or navground)"
        ) from exc

    profile = run.profile
    rng = np.random.default_rng(run.seed)
    starts = [(float(x), float(y), float(th)) for x, y, th in (r.start for r in scenario.robots)]
    if not run.robots.disturbed:  # break HL's symmetric freeze (the noise does it otherwise)
        starts = [
            (x + float(dx), y + float(dy), theta + float(dt))
            for (x, y, theta), (dx, dy, dt) in zip(
                starts,
                rng.normal(0.0, [START_NOISE[0], START_NOISE[0], START_NOISE[1]], (len(starts), 3)),
                strict=True,
            )
        ]
    robots = run.robots.build(starts, profile, run.seed, run.dt)
    clock, drives, link = robots.clock, robots.drives, robots.link
    discs, lines = _navground_obstacles(scenario, core)
    # Where the discs are and how far each may be to be seen (one array op per robot-tick).
    disc_xy = np.array([d.position for d in discs], dtype=np.float64).reshape(-1, 2)
    disc_reach = np.array([VIEW_RANGE_M + d.radius for d in discs], dtype=np.float64)
    kinematics = core.kinematics.TwoWheelsDifferentialDriveKinematics(
        max_speed=profile.wheel_radius * profile.max_wheel_speed,
        wheel_axis=2.0 * profile.half_axle,
    )
    behaviours = []
    for _ in scenario.robots:
        behaviour = core.Behavior.make_type(BEHAVIOURS[run.behaviour])
        if behaviour is None:  # the wheel lacks a behaviour it used to have
            raise ValueError(f"navground has no behaviour {BEHAVIOURS[run.behaviour]!r}")
        behaviour.kinematics = kinematics
        behaviour.radius = profile.radius
        behaviour.safety_margin = max(0.0, run.safety_separation_m - 2.0 * profile.radius)
        behaviours.append(behaviour)

    n = len(behaviours)
    route_of = _router(scenario, profile, run.contact_margin_m)
    via: list[list[tuple[float, float]]] = [[] for _ in range(n)]  # via-points still to pass
    goals: list[Any] = [None] * n  # each robot's pose target, after its via-points
    pass_m = PlannerConfig().pass_m
    owner = assign_goals(scenario)
    pending = sorted(range(len(owner)), key=lambda k: scenario.robots[k].arrival_s)
    tasked = np.zeros(n, dtype=bool)
    arrived = np.zeros(n, dtype=bool)
    known: list[dict[int, _PeerState]] = [{} for _ in range(n)]  # receiver -> sender -> state
    velocity = np.zeros((n, 2))  # commanded, world frame [m/s]
    tolerance = scenario.tolerance
    seq = 0
    end = scenario.end_s
    while True:
        t = np.empty(run.chunk_ticks)
        poses = np.empty((run.chunk_ticks, n, 3))
        modes = np.empty((run.chunk_ticks, n), dtype=np.uint8)
        k = 0
        done = False
        while k < run.chunk_ticks:
            now = clock.now()
            while pending and scenario.robots[pending[0]].arrival_s <= now + 1e-9:
                task = pending.pop(0)
                gx, gy, gtheta = scenario.robots[task].goal
                robot = owner[task]
                if robot < 0:
                    continue  # more tasks than robots: this one is never served
                here = drives[robot].read_pose()[0]
                via[robot] = list(route_of((here.x, here.y), (gx, gy, gtheta)))
                goals[robot] = core.Target.Pose(
                    core.Pose2((gx, gy), gtheta), tolerance.position, tolerance.heading
                )
                behaviours[robot].target = _next_target(core, via[robot], goals[robot], pass_m)
                tasked[robot], arrived[robot] = True, False
            if link is not None:
                for receiver, state in link.deliver(now):
                    old = known[receiver].get(state.sender)
                    if old is None or state.seq > old.seq:
                        known[receiver][state.sender] = state
            measured = np.array([d.read_pose()[0].as_tuple() for d in drives]).reshape(n, 3)
            if link is None:  # every robot sees every pose of this tick at once
                now_states = [_PeerState(j, seq, *measured[j, :2], *velocity[j]) for j in range(n)]
                known = [{j: s for j, s in enumerate(now_states) if j != r} for r in range(n)]
            t[k] = now
            for r, drive in enumerate(drives):
                poses[k, r] = drive.true_pose
            for r, behaviour in enumerate(behaviours):
                x, y, theta = measured[r]
                behaviour.pose = core.Pose2((x, y), theta)
                while via[r] and behaviour.check_if_target_satisfied():  # passed a via-point
                    via[r].pop(0)
                    behaviour.target = _next_target(core, via[r], goals[r], pass_m)
                if tasked[r] and not arrived[r] and behaviour.check_if_target_satisfied():
                    arrived[r] = True
                if not tasked[r] or arrived[r]:
                    drives[r].stop()
                    velocity[r] = 0.0
                    continue
                env = behaviour.environment_state
                assert isinstance(env, core.GeometricState)  # every behaviour here is geometric
                env.neighbors = [
                    core.Neighbor((p.x, p.y), profile.radius, (p.vx, p.vy), p.sender)
                    for p in known[r].values()
                    if math.hypot(p.x - x, p.y - y) <= VIEW_RANGE_M
                ]
                seen = np.hypot(disc_xy[:, 0] - x, disc_xy[:, 1] - y) <= disc_reach
                env.static_obstacles = [discs[k] for k in np.flatnonzero(seen)]
                env.line_obstacles = [
                    line for line, near in lines if near.distance(x, y) <= VIEW_RANGE_M
                ]
                cmd = behaviour.compute_cmd(run.dt)
                behaviour.actuate(cmd, run.dt)  # its own velocity: the one commanded
                vx, vy = (float(v) for v in cmd.velocity)
                if cmd.frame == core.Frame.relative:
                    u = vx
                    vx, vy = u * math.cos(theta), u * math.sin(theta)
                else:
                    u = vx * math.cos(theta) + vy * math.sin(theta)
                velocity[r] = (vx, vy)
                drives[r].command_wheels(*_wheels(u, float(cmd.angular_speed), profile))
            if link is not None:
                for j in range(n):
                    link.send(j, _PeerState(j, seq, *measured[j, :2], *velocity[j]), now)
            seq += 1
            modes[k] = np.where(arrived, _ARRIVED, np.where(tasked, _DRIVING, _IDLE))
            k += 1
            if (not pending and arrived[tasked].all()) or now >= end:
                done = True
                break
            clock.advance(run.dt)
        yield TraceChunk(t=t[:k], poses=poses[:k], modes=modes[:k])
        if done:
            return
