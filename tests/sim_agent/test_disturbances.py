"""DisturbedDrive: pose noise, actuation noise and command latency around a SimDrive."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pytest

from fleet.cli.sim import disturbances_from, link_from, register
from fleet.core.params import RobotProfile
from fleet.io.settings import load_settings
from fleet.io.trace import read_header, read_trace
from robot_agent.clock import SteppedClock
from sim_agent.disturbances import (
    REALISTIC,
    REALISTIC_LINK,
    DelayedLink,
    Disturbances,
    DisturbedDrive,
    LinkDisturbances,
)
from sim_agent.drive import SimDrive
from sim_agent.fleet import SimFleet, Spawn

DT = 0.02
PROFILE = RobotProfile()


def _drive(d: Disturbances, seed: int = 1) -> tuple[DisturbedDrive, SteppedClock]:
    clock = SteppedClock()
    return DisturbedDrive((0.0, 0.0, 0.0), PROFILE, clock, d, np.random.default_rng(seed)), clock


def _commands(k: int) -> tuple[float, float]:
    return 10.0 + 5.0 * math.sin(0.1 * k), 10.0 - 5.0 * math.cos(0.07 * k)


def test_without_disturbances_it_is_the_bare_sim_drive() -> None:
    disturbed, clock = _drive(Disturbances())
    bare = SimDrive((0.0, 0.0, 0.0), PROFILE, clock, max_step=DT)
    for k in range(300):
        for drive in (disturbed, bare):
            drive.read_pose()
            drive.command_wheels(*_commands(k))
        clock.advance(DT)
    assert disturbed.read_pose()[0] == bare.read_pose()[0]
    assert disturbed.true_pose == bare.true_pose


def test_a_command_takes_effect_after_its_latency() -> None:
    drive, clock = _drive(Disturbances(latency_s=(0.1, 0.1)))
    drive.command_wheels(20.0, 20.0)  # 1 m/s straight ahead, from t = 0.1 s on
    xs = []
    for _ in range(10):
        clock.advance(DT)
        xs.append(drive.read_pose()[0].x)
    assert xs[:5] == [0.0] * 5  # t = 0.02 .. 0.10: still standing
    assert xs[-1] == pytest.approx(0.1, abs=1e-9)  # t = 0.2: moved for 0.1 s at 1 m/s
    drive.stop()  # the stop is late too: the robot drives on for 0.1 s
    clock.advance(0.3)
    drive.read_pose()
    assert drive.true_pose[0] == pytest.approx(0.2, abs=1e-9)


def test_commands_keep_their_order_whatever_their_delays() -> None:
    drive, clock = _drive(Disturbances(latency_s=(0.05, 0.15)), seed=3)
    for k in range(50):
        drive.command_wheels(float(k % 20), float(k % 20))
        clock.advance(DT)
        assert drive.pending_commands <= 0.15 / DT + 1  # bounded by the latency
    drive.command_wheels(0.0, 0.0)
    clock.advance(0.2)
    drive.read_pose()
    assert drive.inner.right == 0.0 and drive.pending_commands == 0  # the last one won


def test_pose_noise_is_reported_only_with_the_configured_spread() -> None:
    drive, _ = _drive(Disturbances(pose_noise_m=0.01, heading_noise_rad=0.02))
    readings = np.array([drive.read_pose()[0].as_tuple() for _ in range(4000)])
    assert drive.true_pose == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(readings.std(axis=0), [0.01, 0.01, 0.02], rtol=0.06)
    np.testing.assert_allclose(readings.mean(axis=0), [0, 0, 0], atol=0.002)


def test_actuation_noise_is_unbiased_clipped_and_seeded() -> None:
    noisy, _ = _drive(Disturbances(actuation_noise=0.05))
    applied = []
    for _ in range(2000):
        noisy.command_wheels(10.0, PROFILE.max_wheel_speed)
        applied.append((noisy.inner.right, noisy.inner.left))
    right, left = np.array(applied).T
    assert right.mean() == pytest.approx(10.0, rel=0.01) and right.std() == pytest.approx(
        0.5, rel=0.1
    )
    assert left.max() <= PROFILE.max_wheel_speed  # a motor cannot exceed its limit
    again, _ = _drive(Disturbances(actuation_noise=0.05))
    again.command_wheels(10.0, 10.0)
    first, _ = _drive(Disturbances(actuation_noise=0.05))
    first.command_wheels(10.0, 10.0)
    assert (again.inner.right, again.inner.left) == (first.inner.right, first.inner.left)


def test_a_wheel_bias_curves_a_straight_command() -> None:
    drive, clock = _drive(Disturbances(actuation_bias=0.02), seed=5)
    drive.command_wheels(10.0, 10.0)
    clock.advance(5.0)
    x, y, theta = drive.read_pose()[0].as_tuple()
    assert x > 2.0 and theta != 0.0 and abs(y) > 1e-3  # straight command, curved path


def test_bad_disturbances_are_refused() -> None:
    with pytest.raises(ValueError, match="latency"):
        Disturbances(latency_s=(0.2, 0.1))
    with pytest.raises(ValueError, match="finite"):
        Disturbances(pose_noise_m=-1.0)
    with pytest.raises(ValueError, match="exceeds"):  # the inner drive refuses it
        _drive(Disturbances(actuation_noise=0.05))[0].command_wheels(
            PROFILE.max_wheel_speed * 1.1, 0.0
        )


def _sim_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    commands = parser.add_subparsers()
    register(commands, None)
    return parser.parse_args(["sim", *argv])


def test_sim_flags_build_the_disturbances() -> None:
    assert disturbances_from(_sim_args()) == Disturbances()
    assert not disturbances_from(_sim_args()).active
    assert disturbances_from(_sim_args("--disturbed")) == REALISTIC
    d = disturbances_from(_sim_args("--disturbed", "--latency", "20", "--heading-noise", "1"))
    assert d.latency_s == (0.02, 0.02) and d.heading_noise_rad == pytest.approx(math.radians(1))
    assert d.pose_noise_m == REALISTIC.pose_noise_m
    assert disturbances_from(_sim_args("--noise", "0.05")).heading_noise_rad == pytest.approx(0.01)
    with pytest.raises(SystemExit):
        _sim_args("--latency", "150,50")


def test_sim_flags_build_the_link() -> None:
    assert not link_from(_sim_args()).active
    assert link_from(_sim_args("--disturbed")) == REALISTIC_LINK
    link = link_from(_sim_args("--disturbed", "--link-loss", "0.2", "--link-delay", "40"))
    assert link == LinkDisturbances(delay_s=(0.04, 0.04), loss=0.2)
    with pytest.raises(SystemExit):
        _sim_args("--link-loss", "1.5")
    with pytest.raises(ValueError, match="loss"):
        LinkDisturbances(loss=1.0)


def test_the_link_delays_each_copy_within_its_bounds_and_loses_its_share() -> None:
    link: DelayedLink[int] = DelayedLink(4, DT, REALISTIC_LINK, np.random.default_rng(3))
    delays: list[float] = []
    receivers: set[tuple[int, int]] = set()
    sends = 500
    for k in range(sends + 20):
        now = k * DT
        for receiver, (sender, sent) in link.deliver(now):
            assert receiver != sender
            receivers.add((sender, receiver))
            delays.append(now - sent)
        if k < sends:
            link.send(k % 4, (k % 4, now), now)
    assert len(receivers) == 12  # every ordered pair, never to itself
    assert min(delays) >= 0.02 - 1e-9 and max(delays) <= 0.2 + DT + 1e-9
    assert len(delays) == link.sent - link.lost and link.sent == 3 * sends
    assert 0.03 < link.lost / link.sent < 0.07
    again: DelayedLink[int] = DelayedLink(4, DT, REALISTIC_LINK, np.random.default_rng(3))
    for k in range(sends):
        again.send(k % 4, 0, k * DT)
    assert again.lost == link.lost  # seeded


def test_on_a_disturbed_link_a_robot_sees_its_peer_only_once_the_state_arrives() -> None:
    spawns = [Spawn("a", 0.0, 0.0, 0.0), Spawn("b", 3.0, 0.0, math.pi)]
    link = LinkDisturbances(delay_s=(0.1, 0.1))
    fleet = SimFleet(None, load_settings(), spawns, link=link, seed=2)
    try:
        seen = []
        for _ in range(8):
            fleet.tick()
            b_knows = fleet.views[1].states().get("a")
            seen.append(None if b_knows is None else b_knows.seq)
            assert "b" not in fleet.views[0].states() or fleet.views[0].states()["b"].seq <= max(
                0, len(seen) - 6
            )
    finally:
        fleet.close()
    # a's state of tick k (t = k dt) reaches b at t + 0.1 s, five ticks later, before b senses
    assert seen == [None, None, None, None, None, 0, 1, 2]


def test_a_disturbed_fleet_traces_every_robot_at_every_tick(tmp_path: Path) -> None:
    spawns = [Spawn("a", 0.0, 0.0, 0.0), Spawn("b", 3.0, 0.0, math.pi)]
    path = tmp_path / "fleet.trace"
    fleet = SimFleet(None, load_settings(), spawns, disturbances=REALISTIC, seed=2, trace=path)
    try:
        assert all(isinstance(d, DisturbedDrive) for d in fleet.drives.values())
        for _ in range(30):
            fleet.tick()
    finally:
        fleet.close()
    header = read_header(path)
    assert header.robots == ("a", "b") and header.radii == (0.2, 0.2)
    (chunk,) = list(read_trace(path))
    np.testing.assert_allclose(chunk.t, np.arange(30) * header.period_s)
    np.testing.assert_array_equal(chunk.poses[:, 1], [[3.0, 0.0, math.pi]] * 30)
    assert {header.modes[m] for m in chunk.modes.ravel()} == {"idle"}
