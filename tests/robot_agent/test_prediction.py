"""The own prediction and the peer radius (robot_agent.prediction): exact on constant
commands (the drive's own Euler update), and their radii hold the truth for every latency
in the window, in-order jitter, actuation and pose errors within the stated bounds."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.params import RobotProfile, SafetyConfig
from fleet.core.step import body_velocities, integrate_wheels
from robot_agent.clock import SteppedClock
from robot_agent.latency import LatencyWindow
from robot_agent.prediction import (
    CommandLog,
    measured_spread,
    peer_spread,
    point_speed,
    predict_own,
    sent_window,
)
from sim_agent.disturbances import Disturbances, DisturbedDrive

PROFILE = RobotProfile()
DT = 0.02
SAFETY = SafetyConfig()
EXACT = SafetyConfig(pose_error_m=0.0, heading_error_rad=0.0, actuation_error=0.0)
LIMIT = PROFILE.max_wheel_speed

Posture = tuple[float, float, float]
Schedule = list[tuple[float, float, float]]  # (instant it turns [s], right, left [rad/s])


def _projected(pose: Posture, ahead: float = SAFETY.projection_m) -> tuple[float, float]:
    return pose[0] + ahead * math.cos(pose[2]), pose[1] + ahead * math.sin(pose[2])


def _drive_through(pose: Posture, t0: float, schedule: Schedule, t1: float) -> Posture:
    """The true pose at ``t1`` [s] from ``pose`` at ``t0`` under the wheels of ``schedule``
    (each from its instant on; standing before the first), in Euler steps of at most DT
    split at every switch, as the simulated drive integrates."""
    x, y, theta = pose
    t = t0
    right = left = 0.0
    for at, r, left_ in schedule:
        if at <= t0:
            right, left = r, left_
    points = sorted({at for at, _, _ in schedule if t0 < at < t1} | {t1})
    for end in points:
        if end > t:
            steps = max(1, math.ceil((end - t) / DT - 1e-9))
            x, y, theta = integrate_wheels(
                x, y, theta, right, left, PROFILE.wheel_radius, PROFILE.half_axle,
                (end - t) / steps, steps,
            )  # fmt: skip
            t = end
        for at, r, left_ in schedule:
            if at == end:
                right, left = r, left_
    return x, y, theta


wheel = st.floats(-LIMIT, LIMIT, allow_nan=False)


@st.composite
def histories(draw: st.DrawFn) -> dict[str, object]:
    """Commands sent every DT (some repeating the one before), a latency window, each
    command's true latency (one for all, or drawn per command and kept in order), and
    wheel errors within the actuation bound."""
    n = draw(st.integers(1, 20))
    commands: list[tuple[float, float]] = []
    for _ in range(n):
        if commands and draw(st.booleans()):
            commands.append(commands[-1])
        else:
            commands.append((draw(wheel), draw(wheel)))
    lo = draw(st.floats(0.0, 0.2))
    hi = lo + draw(st.floats(0.0, 0.12))
    jitter = draw(st.booleans())
    latency = st.floats(lo, hi)
    fixed = draw(latency)
    latencies = [draw(latency) if jitter else fixed for _ in range(n + 1)]
    error = st.floats(-1.0, 1.0)
    slips = [(draw(error), draw(error)) for _ in range(n)]
    return {
        "commands": commands,
        "window": LatencyWindow(lo, hi, measured=True),
        "latencies": latencies,
        "slips": slips,
        "new": (draw(wheel), draw(wheel)),
        "age": draw(st.integers(0, 2)) * DT,
        "start": (draw(st.floats(-5, 5)), draw(st.floats(-5, 5)), draw(st.floats(-4, 4))),
        "noise": (draw(st.floats(0, 1)), draw(st.floats(-math.pi, math.pi)), draw(error)),
        "instant": draw(st.floats(0.0, 1.0)),
    }


def _true_schedule(
    commands: list[tuple[float, float]], latencies: list[float], slips: list[tuple[float, float]]
) -> Schedule:
    """When each command really turns (in order: a command held up holds up the ones behind
    it) and the wheels it really turns (its actuation error)."""
    schedule: Schedule = []
    due = -math.inf
    e = SAFETY.actuation_error
    for k, ((right, left), latency, (sr, sl)) in enumerate(
        zip(commands, latencies, slips, strict=True)
    ):
        due = max(k * DT + latency, due)
        schedule.append((due, right * (1 + e * sr), left * (1 + e * sl)))
    return schedule


@settings(max_examples=300, deadline=None)
@given(histories())
def test_the_own_spread_holds_the_true_pose_when_the_command_acts(h: dict[str, object]) -> None:
    commands = h["commands"]
    window = h["window"]
    latencies = h["latencies"]
    assert isinstance(commands, list) and isinstance(window, LatencyWindow)
    assert isinstance(latencies, list)
    n = len(commands)
    now = n * DT
    measured_at = now - float(h["age"])  # type: ignore[arg-type]
    schedule = _true_schedule(commands, latencies[:n], h["slips"])  # type: ignore[arg-type]
    start = h["start"]
    assert isinstance(start, tuple)
    true_then = _drive_through(start, 0.0, schedule, measured_at)
    radius, bearing, heading_error = h["noise"]  # type: ignore[misc]
    measured = (
        true_then[0] + SAFETY.pose_error_m * radius * math.cos(bearing),
        true_then[1] + SAFETY.pose_error_m * radius * math.sin(bearing),
        true_then[2] + SAFETY.heading_error_rad * heading_error,
    )
    log = CommandLog(span_s=1.0)
    for k, (right, left) in enumerate(commands):
        log.add(k * DT, right, left)
    prediction = predict_own(measured, measured_at, now, log, window, PROFILE, SAFETY, DT)

    # The new command acts at its due instant: anywhere in the window, after those before.
    acts = max(now + latencies[n], schedule[-1][0])
    true_when = _drive_through(true_then, measured_at, schedule, acts)
    miss = math.dist(_projected(true_when), _projected(prediction.pose))
    assert miss <= prediction.spread + 1e-9, (miss, prediction.spread)

    # What peers are told holds the truth at the nominal instant, the new command in.
    right, left = h["new"]  # type: ignore[misc]
    ahead = prediction.ahead(right, left, PROFILE, SAFETY, lead=window.nominal)
    with_new = [*schedule, (acts, right, left)]
    true_nominal = _drive_through(true_then, measured_at, with_new, prediction.at)
    assert math.dist(true_nominal[:2], prediction.pose[:2]) <= ahead.spread_m + 1e-9
    assert abs(true_nominal[2] - prediction.pose[2]) <= ahead.heading_rad + 1e-9
    in_flight = [c for k, c in enumerate(commands) if k * DT >= measured_at - window.hi - DT]
    speeds = [
        point_speed(*body_velocities(r, le, PROFILE.wheel_radius, PROFILE.half_axle),
                    PROFILE.half_axle, SAFETY)
        for r, le in [*in_flight, (right, left)]
    ]  # fmt: skip
    assert ahead.speed_m_s >= max(speeds)


@settings(max_examples=100, deadline=None)
@given(
    right=wheel,
    left=wheel,
    latency_steps=st.integers(0, 8),
    start=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-4, 4)),
)
def test_the_prediction_is_the_drive_s_pose_on_constant_commands(
    right: float, left: float, latency_steps: int, start: Posture
) -> None:
    """A drive with a fixed latency, commanded the same wheels every tick: the pose the
    agent predicts for the instant its command acts is where the drive is then (the same
    Euler update, one implementation), and with exact measurements nothing is uncertain."""
    latency = latency_steps * DT
    clock = SteppedClock()
    drive = DisturbedDrive(
        start, PROFILE, clock, Disturbances(latency_s=(latency, latency)),
        np.random.default_rng(0), max_step=DT,
    )  # fmt: skip
    log = CommandLog(span_s=1.0)
    window = LatencyWindow(latency, latency, measured=True)
    predictions = []
    for _ in range(30):
        pose, stamp = drive.read_pose()
        now = clock.now()
        prediction = predict_own(pose.as_tuple(), stamp, now, log, window, PROFILE, EXACT, DT)
        predictions.append((prediction, round(prediction.at / DT)))
        drive.command_wheels(right, left)
        log.add(now, right, left)
        clock.advance(DT)
    truth = {}
    for _ in range(10):
        truth[round(clock.now() / DT)] = drive.read_pose()[0].as_tuple()
        drive.command_wheels(right, left)
        clock.advance(DT)
    for prediction, tick in predictions:
        if tick in truth:
            np.testing.assert_allclose(prediction.pose, truth[tick], rtol=0, atol=1e-9)
            # exact measurements: only the Euler allowance is left
            assert prediction.spread <= DT * prediction.horizon * prediction.turn + 1e-12
    _, omega = body_velocities(right, left, PROFILE.wheel_radius, PROFILE.half_axle)
    if omega == 0.0:  # a straight line: Euler is exact
        prediction = predictions[-1][0]
        assert prediction.spread == 0.0


@st.composite
def peers(draw: st.DrawFn) -> dict[str, object]:
    """A peer's commands (speed-ups capped as every agent caps them), its wheel errors, its
    latency, the state it publishes, the link delay, and this robot's window."""
    n = draw(st.integers(2, 40))
    limit = 0.0
    commands = []
    for _ in range(n):
        right, left = draw(wheel), draw(wheel)
        u, omega = body_velocities(right, left, PROFILE.wheel_radius, PROFILE.half_axle)
        speed = point_speed(u, omega, PROFILE.half_axle, SAFETY)
        limit += SAFETY.max_accel_m_s2 * DT
        if speed > limit:
            right, left = right * limit / speed, left * limit / speed
            speed = limit
        limit = speed
        commands.append((right, left))
    lo = draw(st.floats(0.0, 0.15))
    hi = lo + draw(st.floats(0.0, 0.1))
    own_lo = draw(st.floats(0.0, 0.15))
    error = st.floats(-1.0, 1.0)
    return {
        "commands": commands,
        "slips": [(draw(error), draw(error)) for _ in range(n)],
        "window": LatencyWindow(lo, hi, measured=True),
        "latency": draw(st.floats(lo, hi)),
        "published": draw(st.integers(1, n - 1)),
        "delay": draw(st.floats(0.0, SAFETY.link_delay_s)),
        "silence": draw(st.integers(0, 10)) * DT,
        "own": LatencyWindow(own_lo, own_lo + draw(st.floats(0.0, 0.1)), measured=True),
        "instant": draw(st.floats(0.0, 1.0)),
        "start": (draw(st.floats(-5, 5)), draw(st.floats(-5, 5)), draw(st.floats(-4, 4))),
    }


@settings(max_examples=300, deadline=None)
@given(peers())
def test_a_peer_s_radius_holds_it_whenever_this_robot_s_command_may_act(
    p: dict[str, object],
) -> None:
    """The peer publishes its prediction at its k-th command; the state arrives after a
    delay within link_delay_s and the robot decides some ticks later. Wherever the peer's
    later commands take it (any direction: its filter may brake or swerve; only speed-ups
    are capped), its true projected point at any instant of the robot's window lies within
    peer_spread of the one it predicted -- and within measured_spread of the pose it
    measured."""
    commands = p["commands"]
    window, own = p["window"], p["own"]
    assert isinstance(commands, list) and isinstance(window, LatencyWindow)
    assert isinstance(own, LatencyWindow)
    k = int(p["published"])  # type: ignore[call-overload]
    latency = float(p["latency"])  # type: ignore[arg-type]
    schedule = _true_schedule(commands, [latency] * len(commands), p["slips"])  # type: ignore[arg-type]
    start = p["start"]
    assert isinstance(start, tuple)
    sent = k * DT
    true_then = _drive_through(start, 0.0, schedule, sent)
    log = CommandLog(span_s=1.0)
    for i, (right, left) in enumerate(commands[:k]):
        log.add(i * DT, right, left)
    prediction = predict_own(true_then, sent, sent, log, window, PROFILE, SAFETY, DT)
    right, left = commands[k]
    ahead = prediction.ahead(right, left, PROFILE, SAFETY, lead=window.nominal)

    heard = sent + float(p["delay"])  # type: ignore[arg-type]
    now = heard + float(p["silence"])  # type: ignore[arg-type]
    instant = now + own.lo + float(p["instant"]) * (own.hi - own.lo)  # type: ignore[arg-type]
    truth = _drive_through(start, 0.0, schedule, instant)
    centre = (ahead.x, ahead.y, ahead.theta)
    for sent_age in (None, (heard - sent, heard - sent)):  # by the link bound; by the stamp
        sent_within = sent_window(heard, sent_age, SAFETY)
        radius = peer_spread(ahead, sent_within, now, own, SAFETY)
        assert math.dist(_projected(truth), _projected(centre)) <= radius + 1e-9
        measured = measured_spread(ahead, sent_within, sent, now, own, SAFETY)
        assert math.dist(_projected(truth), _projected(true_then)) <= measured + 1e-9
