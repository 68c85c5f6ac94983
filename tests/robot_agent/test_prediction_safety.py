"""The safety filter's guarantee with latency where it lives (docs/safety.md): robots decide
on their poses predicted for the instant their commands act, and see their peers where the
peers predicted themselves, from states that arrive late or never -- and no step brings two
bodies, or a body and an obstacle's body, within the margin.

The model: Euler steps of the control period; each robot's commands act a whole number of
steps after they are sent, a number unknown to it but within its latency window; its wheels
turn within the actuation error of its commands; its pose is measured within the pose and
heading errors; its state reaches each peer one to ``link_delay_s`` later, or is lost (its
send time known from its stamp, synchronised clocks, or only within that bound); every
robot runs the agent's pure pieces: :func:`robot_agent.prediction.predict_own`, a
:class:`~robot_agent.world.WorldView` (``peer_bodies`` with its window), the filter (the
reference step, equal to the compiled one bit for bit: test_reference.py) and
:func:`robot_agent.logic.cap_speed_up`.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fleet.core import reference as ref
from fleet.core.params import RobotProfile, SafetyConfig
from fleet.core.step import body_velocities, wheel_speeds
from fleet.core.wire import Pose, RobotState
from robot_agent.clock import SteppedClock
from robot_agent.latency import LatencyWindow
from robot_agent.logic import TickResult, cap_speed_up
from robot_agent.prediction import CommandLog, point_speed, predict_own
from robot_agent.world import WorldView

RADIUS = 0.2
DT = 0.02
PROFILE = RobotProfile(max_wheel_speed=20.0, radius=RADIUS)
LIMIT = ref.WheelLimit(PROFILE.wheel_radius, PROFILE.half_axle, PROFILE.max_wheel_speed)
SAFETY = SafetyConfig(link_delay_s=0.2)
MARGIN, PROJECTION = SAFETY.contact_margin_m, SAFETY.projection_m
DELAY_STEPS = round(SAFETY.link_delay_s / DT)
WHEEL_GEOMETRY = (PROFILE.wheel_radius, PROFILE.half_axle)

coordinate = st.floats(-2.0, 2.0, allow_nan=False)
heading = st.floats(-math.pi, math.pi, allow_nan=False)
pose = st.tuples(coordinate, coordinate, heading)


def _clear(poses: list[tuple[float, float, float]], obstacles: list[ref.ObstacleRow]) -> bool:
    """Every projected disc clear of the others and of the obstacles at t = 0."""
    points = [(x + PROJECTION * math.cos(t), y + PROJECTION * math.sin(t)) for x, y, t in poses]
    for i, a in enumerate(points):
        for b in points[i + 1 :]:
            if math.dist(a, b) < 2 * (RADIUS + PROJECTION) + MARGIN + 1e-6:
                return False
        for obstacle in obstacles:
            if math.hypot(*ref.obstacle_offset(obstacle, *a)) < (
                RADIUS + PROJECTION + obstacle[3] + MARGIN + 1e-6
            ):
                return False
    return True


@st.composite
def scenes(draw: st.DrawFn) -> dict[str, object]:
    n = draw(st.integers(2, 4))
    starts = draw(st.lists(pose, min_size=n, max_size=n))
    post = st.tuples(coordinate, coordinate, st.just(0.6), st.floats(0.0, 0.3))
    wall = st.tuples(post, coordinate, coordinate).map(lambda w: (*w[0], w[1], w[2]))
    obstacles = draw(st.lists(st.one_of(post, wall), max_size=3))
    assume(_clear(starts, obstacles))
    windows = []
    for _ in range(n):
        lo = draw(st.integers(0, 8))
        hi = lo + draw(st.integers(0, 6))
        windows.append((lo, draw(st.integers(lo, hi)), hi))  # (lo, true, hi) [steps]
    # Mostly swaps (each robot's goal is another's start, heading on): robots meet.
    if draw(st.booleans()):
        shift = draw(st.integers(1, n - 1))
        goals = [(*starts[(i + shift) % n][:2], draw(heading)) for i in range(n)]
    else:
        goals = draw(st.lists(pose, min_size=n, max_size=n))
    return {
        "starts": starts,
        "goals": goals,
        "laws": draw(st.lists(st.sampled_from(["cw", "ccw"]), min_size=n, max_size=n)),
        "obstacles": obstacles,
        "windows": windows,
        "k_avoid": draw(st.sampled_from([0.0, 0.3])),
        "seed": draw(st.integers(0, 2**32 - 1)),
        "loss": draw(st.sampled_from([0.0, 0.2])),
        "rate": draw(st.sampled_from([5.0, 20.0, 50.0])),
        "jitter": draw(st.booleans()),
        "synced": draw(st.booleans()),
    }


def _smallest_clearance(
    poses: list[tuple[float, float, float]], obstacles: list[ref.ObstacleRow]
) -> float:
    smallest = math.inf
    for i, a in enumerate(poses):
        for b in poses[i + 1 :]:
            smallest = min(smallest, math.dist(a[:2], b[:2]) - 2 * RADIUS)
        for obstacle in obstacles:
            distance = math.hypot(*ref.obstacle_offset(obstacle, a[0], a[1]))
            smallest = min(smallest, distance - RADIUS - obstacle[3])
    return smallest


def run_model(scene: dict[str, object], seconds: float = 4.0) -> list[float]:
    """The clearances [m] after every step of the scene (module docstring)."""
    starts = scene["starts"]
    goals = scene["goals"]
    laws = scene["laws"]
    obstacles = scene["obstacles"]
    windows = scene["windows"]
    assert isinstance(starts, list) and isinstance(goals, list) and isinstance(laws, list)
    assert isinstance(obstacles, list) and isinstance(windows, list)
    rng = np.random.default_rng(int(scene["seed"]))  # type: ignore[call-overload]
    loss = float(scene["loss"])  # type: ignore[arg-type]
    n = len(starts)
    ids = [f"r{i}" for i in range(n)]
    clock = SteppedClock()
    views = [WorldView(clock.now) for _ in range(n)]
    logs = [CommandLog(span_s=1.0) for _ in range(n)]
    latency = [LatencyWindow(lo * DT, hi * DT, measured=True) for lo, _, hi in windows]
    acting: list[dict[int, tuple[float, float]]] = [{} for _ in range(n)]  # step -> wheels
    in_transit: dict[int, list[tuple[int, RobotState]]] = {}  # step -> (receiver, state)
    last_speed = [0.0] * n
    wheels_now = [(0.0, 0.0)] * n
    done = [False] * n
    avoidance = ref.Avoidance(float(scene["k_avoid"]), 1.0, 0.05, RADIUS)  # type: ignore[arg-type]
    rate = float(scene["rate"])  # type: ignore[arg-type]
    jitter = bool(scene.get("jitter", False))
    synced = bool(scene.get("synced", False))
    last_due = [0] * n
    true = [tuple(map(float, s)) for s in starts]
    clearances: list[float] = []
    e_pose, e_heading, e_wheel = SAFETY.pose_error_m, SAFETY.heading_error_rad, 0.0
    e_wheel = SAFETY.actuation_error
    for k in range(round(seconds / DT)):
        now = clock.now()
        for receiver, state in in_transit.pop(k, []):
            age = now - state.stamp  # stamps on the one clock: synchronised
            views[receiver].update_state(state, sent_age_s=(age, age) if synced else None)
        decided = []
        for i in range(n):
            x, y, theta = true[i]
            bearing, r = rng.uniform(-math.pi, math.pi), e_pose * math.sqrt(rng.uniform())
            measured = (
                x + r * math.cos(bearing),
                y + r * math.sin(bearing),
                theta + e_heading * rng.uniform(-1.0, 1.0),
            )
            prediction = predict_own(measured, now, now, logs[i], latency[i], PROFILE, SAFETY, DT)
            right = left = u = omega = 0.0
            if not done[i]:
                postures, shapes = views[i].peer_bodies(ids[i], SAFETY, RADIUS, latency[i])
                peers = [
                    ref.Body(*postures[:, j], shapes[0, j], shapes[1, j])
                    for j in range(postures.shape[1])
                ]
                result = ref.step(
                    prediction.pose, goals[i], (1.0, 3.0, 1.0), laws[i] == "cw", DT, LIMIT,
                    avoidance=avoidance, peers=peers, obstacles=obstacles,
                    safety=ref.Safety(
                        MARGIN, PROJECTION, rate, prediction.spread, prediction.heading
                    ),
                )  # fmt: skip
                right, left = wheel_speeds(result.u, result.omega, *WHEEL_GEOMETRY)
                tick = TickResult(
                    mode=None,  # type: ignore[arg-type]
                    task=None,
                    u=result.u,
                    omega=result.omega,
                    right=right,
                    left=left,
                )
                limit = last_speed[i] + SAFETY.max_accel_m_s2 * DT
                tick = cap_speed_up(tick, limit, PROFILE.half_axle, SAFETY)
                right, left, u, omega = tick.right, tick.left, tick.u, tick.omega
                if ref.within_tolerance(result.error, 0.05, 0.02):
                    done[i] = True
            decided.append((right, left))
            logs[i].add(now, right, left)
            last_speed[i] = point_speed(u, omega, PROFILE.half_axle, SAFETY)
            lo, steps, hi = windows[i]
            if jitter:  # each command its own latency in the window, applied in order
                steps = int(rng.integers(lo, hi + 1))
            last_due[i] = max(k + steps, last_due[i])
            acting[i][last_due[i]] = (right, left)
            ahead = prediction.ahead(right, left, PROFILE, SAFETY, lead=prediction.at - now)
            state = RobotState(
                robot_id=ids[i], seq=k, stamp=now, pose=Pose(x=measured[0], y=measured[1],
                theta=measured[2]), u=u, omega=omega, radius=RADIUS, ahead=ahead,
            )  # fmt: skip
            for j in range(n):
                if j != i and rng.uniform() >= loss:
                    due = k + int(rng.integers(1, DELAY_STEPS + 1))
                    in_transit.setdefault(due, []).append((j, state))
        following = []
        for i in range(n):
            if k in acting[i]:  # the command due now takes over (with its wheel errors)
                right, left = acting[i].pop(k)
                slip = rng.uniform(-e_wheel, e_wheel, 2)
                wheels_now[i] = (right * (1 + slip[0]), left * (1 + slip[1]))
            u, omega = body_velocities(*wheels_now[i], LIMIT.wheel_radius, LIMIT.half_axle)
            x, y, theta = true[i]
            following.append(
                (x + math.cos(theta) * u * DT, y + math.sin(theta) * u * DT, theta + omega * DT)
            )
        true = following
        clock.advance(DT)
        clearances.append(_smallest_clearance(true, obstacles))
    return clearances


@settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow],
)
@given(scenes())
def test_no_step_brings_bodies_within_the_margin_when_robots_decide_on_predictions(
    scene: dict[str, object],
) -> None:
    clearances = run_model(scene)
    assert min(clearances) >= MARGIN - 1e-9, min(clearances)
