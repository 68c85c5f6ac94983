"""Independent peers: navground's ORCA, HRVO, HL and social-force behaviours on a scenario.

navground (https://idsia-robotics.github.io/navground, C++ core, on the package index) runs
in this process, on the same robots as the fleet's: two-wheel differential drive with the
profile's wheel limit (``max_speed`` = wheel radius x max wheel speed, the rim speed [m/s];
``wheel_axis`` = 2 x half axle), no reversing (navground's default), the same body radius,
the agents' control period as time step, the fleet's safety separation (navground's
``safety_margin`` = separation - 2 x radius, added once to a pair's distance; social force
ignores it), the scenario's pose targets and tolerances
(``GoToPoseTask``: these behaviours steer to a *position*; navground then turns the robot
in place to the goal heading) and its time limit. Tasks arrive at their ``arrival_s``; an
unnamed scenario's goals go to idle robots by an optimal assignment on straight-line
distance (scipy's Hungarian method), one arrival group at a time.

Ticks come out as :class:`~fleet.io.trace.TraceChunk` -- the same form as a ``parkfleet
sim`` trace -- so :class:`~fleet.bench.metrics.RunMetrics` measures both alike. Settings
found on this machine (DESIGN.md): every agent sees peers and obstacles within
:data:`VIEW_RANGE_M` (``BoundedStateEstimation``; a range beyond the yard made HRVO and
social force 2-3x slower on the car park's posts), ``world.ignore_collisions`` so
overlaps are measured instead of being pushed apart, and a seeded start-pose noise of the
size of the fleet robots' pose noise (HL freezes in a perfectly symmetric ring). Static
obstacles are discs of the scenario's body radius. navground's values are float32.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from fleet.bench.scenarios import Scenario
from fleet.core.params import RobotProfile
from fleet.core.types import FloatArray
from fleet.core.wire import RobotMode
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
    dt: float = 0.02
    seed: int = 0
    chunk_ticks: int = 500


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


def run_peer(scenario: Scenario, run: PeerRun) -> Iterator[TraceChunk]:
    """Run ``scenario`` with a navground behaviour; yields its ticks until every task is
    done or the time limit (:attr:`Scenario.end_s`) passes. Raises ValueError for an
    unknown behaviour and ImportError (with the fix) without navground."""
    if run.behaviour not in BEHAVIOURS:
        raise ValueError(
            f"unknown navground behaviour {run.behaviour!r}; one of {list(BEHAVIOURS)}"
        )
    try:
        from navground import core, sim
    except ImportError as exc:  # an optional dependency of the benchmark
        raise ImportError(
            "the navground peers need navground: pip install 'parkfleet[test]' (or navground)"
        ) from exc

    profile = run.profile
    rng = np.random.default_rng(run.seed)
    world = sim.World()
    world.ignore_collisions = True
    for o in scenario.obstacles:
        world.add_obstacle(sim.Obstacle((o.x, o.y), max(o.body, 0.01)))
    agents = []
    for spec in scenario.robots:
        x, y, theta = spec.start
        dx, dy = rng.normal(0.0, START_NOISE[0], size=2)
        behaviour = core.Behavior.make_type(BEHAVIOURS[run.behaviour])
        if behaviour is None:  # the wheel lacks a behaviour it used to have
            raise ValueError(f"navground has no behaviour {BEHAVIOURS[run.behaviour]!r}")
        behaviour.safety_margin = max(0.0, run.safety_separation_m - 2.0 * profile.radius)
        agent = sim.Agent(
            radius=profile.radius,
            behavior=behaviour,
            kinematics=core.kinematics.TwoWheelsDifferentialDriveKinematics(
                max_speed=profile.wheel_radius * profile.max_wheel_speed,
                wheel_axis=2.0 * profile.half_axle,
            ),
            state_estimations=[sim.state_estimations.BoundedStateEstimation(range=VIEW_RANGE_M)],
            control_period=run.dt,
        )
        agent.pose = core.Pose2((x + dx, y + dy), theta + rng.normal(0.0, START_NOISE[1]))
        world.add_agent(agent)
        agents.append(agent)

    owner = assign_goals(scenario)
    pending = sorted(range(len(owner)), key=lambda k: scenario.robots[k].arrival_s)
    tasks: list[sim.tasks.GoToPoseTask | None] = [None] * len(agents)
    tolerance = scenario.tolerance
    n = len(agents)
    ticks = 0
    end = scenario.end_s
    while True:
        t = np.empty(run.chunk_ticks)
        poses = np.empty((run.chunk_ticks, n, 3))
        modes = np.empty((run.chunk_ticks, n), dtype=np.uint8)
        k = 0
        done = False
        while k < run.chunk_ticks:
            now = ticks * run.dt
            while pending and scenario.robots[pending[0]].arrival_s <= now + 1e-9:
                task = pending.pop(0)
                gx, gy, gtheta = scenario.robots[task].goal
                robot = owner[task]
                if robot < 0:
                    continue  # more tasks than robots: this one is never served
                tasks[robot] = sim.tasks.GoToPoseTask(
                    (gx, gy), gtheta, tolerance.position, tolerance.heading
                )
                agents[robot].task = tasks[robot]
            tasked = np.array([task is not None for task in tasks])
            arrived = np.array([task is not None and task.done() for task in tasks])
            t[k] = now
            for r, agent in enumerate(agents):
                px, py = agent.position
                poses[k, r] = (float(px), float(py), float(agent.orientation))
            modes[k] = np.where(arrived, _ARRIVED, np.where(tasked, _DRIVING, _IDLE))
            k += 1
            ticks += 1
            if (not pending and arrived[tasked].all()) or now >= end:
                done = True
                break
            world.update(run.dt)
        yield TraceChunk(t=t[:k], poses=poses[:k], modes=modes[:k])
        if done:
            return
