"""The pose the law decides on (robot_agent.smoothing): exactly the reading on a perfect
drive, much less noisy than the readings on a noisy one, restarted by a jump."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.params import RobotProfile
from robot_agent.clock import SteppedClock
from robot_agent.smoothing import PoseSmoother
from sim_agent.disturbances import Disturbances, DisturbedDrive
from sim_agent.drive import SimDrive

PROFILE = RobotProfile()
DT = 0.02
LIMIT = PROFILE.max_wheel_speed


def _smoother(weight: float = 0.2) -> PoseSmoother:
    return PoseSmoother(weight, PROFILE, DT, jump_m=0.2, jump_rad=0.2, max_gap_s=0.5)


wheel = st.floats(-LIMIT, LIMIT, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(commands=st.lists(st.tuples(wheel, wheel), min_size=1, max_size=60))
def test_on_a_perfect_drive_the_estimate_is_the_reading_bit_for_bit(
    commands: list[tuple[float, float]],
) -> None:
    """A drive that switches its wheels when commanded and reads its pose exactly: the
    odometry carries the estimate exactly where the reading is, so smoothing changes
    nothing (perfect robots, and the planner's model of them, are unchanged)."""
    clock = SteppedClock()
    drive = SimDrive((0.3, -0.2, 1.0), PROFILE, clock)
    smoother = _smoother()
    for right, left in commands:
        pose, stamp = drive.read_pose()
        estimate = smoother.update(pose.as_tuple(), stamp, drive.wheel_speeds())
        assert estimate == pose.as_tuple()
        drive.command_wheels(right, left)
        clock.advance(DT)
    assert smoother.restarts == 0


@settings(max_examples=20, deadline=None)
@given(
    right=st.floats(-LIMIT, LIMIT, allow_nan=False),
    left=st.floats(-LIMIT, LIMIT, allow_nan=False),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_estimate_is_far_less_noisy_than_the_readings(
    right: float, left: float, seed: int
) -> None:
    """Readings with 1 cm and 0.5 degree of Gaussian noise of a robot on any arc, its
    wheels switching 50-150 ms after each command and 5 % off: at weight 0.2 the estimate's
    RMS error is well under half the readings' (a fixed gain w leaves sqrt(w / (2 - w)),
    a third, of white noise), in position and in heading."""
    clock = SteppedClock()
    noisy = Disturbances(
        pose_noise_m=0.01, heading_noise_rad=math.radians(0.5), actuation_noise=0.05,
        latency_s=(0.05, 0.15),
    )  # fmt: skip
    drive = DisturbedDrive((0.0, 0.0, 0.0), PROFILE, clock, noisy, np.random.default_rng(seed))
    smoother = _smoother()
    errors: dict[str, list[float]] = {"reading": [], "estimate": []}
    headings: dict[str, list[float]] = {"reading": [], "estimate": []}
    for tick in range(400):
        pose, stamp = drive.read_pose()
        estimate = smoother.update(pose.as_tuple(), stamp, drive.wheel_speeds())
        truth = drive.true_pose
        if tick >= 50:  # past the start (the estimate starts at a reading)
            for name, p in (("reading", pose.as_tuple()), ("estimate", estimate)):
                errors[name].append(math.hypot(p[0] - truth[0], p[1] - truth[1]))
                headings[name].append(math.remainder(p[2] - truth[2], 2 * math.pi))
        drive.command_wheels(right, left)
        clock.advance(DT)

    def rms(values: list[float]) -> float:
        return float(np.sqrt(np.mean(np.square(values))))

    assert rms(errors["estimate"]) < 0.5 * rms(errors["reading"])
    assert rms(headings["estimate"]) < 0.5 * rms(headings["reading"])
    assert smoother.restarts == 0


def test_a_jump_a_gap_or_a_drive_without_wheel_speeds_restarts_from_the_reading() -> None:
    smoother = _smoother()
    wheels = (0.0, 0.0, 0.0)
    smoother.update((0.0, 0.0, 0.0), 0.0, wheels)
    assert smoother.update((0.01, 0.0, 0.0), 0.02, wheels) == pytest.approx((0.002, 0.0, 0.0))
    # the same reading again (its stamp unchanged): nothing new
    assert smoother.update((0.01, 0.0, 0.0), 0.02, wheels) == pytest.approx((0.002, 0.0, 0.0))
    # relocalised 1 m away: a jump, not noise
    assert smoother.update((1.0, 0.0, 0.0), 0.04, wheels) == (1.0, 0.0, 0.0)
    # a second without readings: the odometry is not trusted over it
    assert smoother.update((1.01, 0.0, 0.0), 1.04, wheels) == (1.01, 0.0, 0.0)
    assert smoother.restarts == 2
    # a drive without wheel speeds keeps its readings (and that is no restart)
    assert smoother.update((1.02, 0.0, 0.0), 1.06, None) == (1.02, 0.0, 0.0)
    assert smoother.restarts == 2
    # weight 1: the reading alone
    off = _smoother(1.0)
    off.update((0.0, 0.0, 0.0), 0.0, wheels)
    assert off.update((0.01, 0.0, 0.0), 0.02, wheels) == (0.01, 0.0, 0.0)


def test_the_heading_is_blended_the_short_way_round_and_keeps_the_readings_wrap() -> None:
    smoother = _smoother(0.5)
    wheels = (0.0, 0.0, 0.0)
    smoother.update((0.0, 0.0, math.pi - 0.01), 0.0, wheels)
    x, y, theta = smoother.update((0.0, 0.0, -math.pi + 0.01), 0.02, wheels)
    assert theta == pytest.approx(-math.pi)  # halfway across the wrap, not through 0


@pytest.mark.parametrize("weight", [0.0, -0.1, 1.5, math.nan])
def test_a_weight_outside_zero_to_one_is_refused(weight: float) -> None:
    with pytest.raises(ValueError, match="weight"):
        _smoother(weight)
