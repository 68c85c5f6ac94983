"""Frames, stamps and the localiser carried forward by odometry (pure)."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from robot_agent.drives.ros2_messages import StampedPose
from robot_agent.drives.ros2_pose import (
    MAX_LOCALISER_LEAD_S,
    RESET_RADIUS_M,
    JumpLimits,
    PoseTrack,
    check_pose,
    compose,
    interpolate,
    invert,
    measured_at,
    odometry_jump,
    wrap_angle,
)

coord = st.floats(-50, 50, allow_nan=False)
angle = st.floats(-10, 10, allow_nan=False)
poses = st.tuples(coord, coord, angle)


def close(a: tuple[float, float, float], b: tuple[float, float, float], tol: float = 1e-9) -> bool:
    return (
        math.isclose(a[0], b[0], abs_tol=tol)
        and math.isclose(a[1], b[1], abs_tol=tol)
        and math.isclose(math.remainder(a[2] - b[2], 2 * math.pi), 0.0, abs_tol=tol)
    )


@given(poses, poses, poses)
def test_compose_is_associative_and_invert_undoes_it(
    a: tuple[float, float, float], b: tuple[float, float, float], c: tuple[float, float, float]
) -> None:
    assert close(compose(compose(a, b), c), compose(a, compose(b, c)), 1e-7)
    assert close(compose(invert(a), compose(a, b)), b, 1e-7)
    assert close(compose(a, invert(a)), (0.0, 0.0, 0.0), 1e-7)
    assert -math.pi <= compose(a, b)[2] < math.pi


def test_origin_moves_a_pose_into_the_world_frame() -> None:
    # the odom frame starts at (2, 1) facing +y: 1 m forward in odom is 1 m along +y
    assert close(compose((2.0, 1.0, math.pi / 2), (1.0, 0.0, 0.0)), (2.0, 2.0, math.pi / 2))


@given(poses, poses, st.floats(0, 1))
def test_interpolate_starts_ends_and_turns_the_short_way(
    a: tuple[float, float, float], b: tuple[float, float, float], f: float
) -> None:
    assert close(interpolate(a, b, 0.0), a) and close(interpolate(a, b, 1.0), b, 1e-7)
    turned = abs(wrap_angle(interpolate(a, b, f)[2] - a[2]))
    assert turned <= abs(wrap_angle(b[2] - a[2])) * f + 1e-7


def reading(stamp: float = 100.0, frame: str = "odom") -> StampedPose:
    return StampedPose(x=1.0, y=2.0, theta=0.0, stamp_s=stamp, frame_id=frame)


def test_check_pose_reasons() -> None:
    assert check_pose(reading(), "odom", wall_now=100.5, max_future_s=0.1) is None
    assert check_pose(reading(frame="/odom"), "odom", 100.5, 0.1) is None  # ROS 1 style
    assert check_pose(reading(100.05), "odom", 100.0, 0.1) is None  # within the skew
    for pose, reason in [
        (reading(frame="map"), "wrong_frame"),
        (reading(0.0), "unstamped"),
        (reading(100.2), "future_stamp"),
    ]:
        rejected = check_pose(pose, "odom", 100.0, 0.1)
        assert rejected is not None and rejected.reason == reason


def test_measured_at_maps_the_stamp_to_the_monotonic_clock() -> None:
    assert measured_at(99.75, wall_now=100.0, monotonic_now=5.0) == 4.75
    assert measured_at(100.05, wall_now=100.0, monotonic_now=5.0) == 5.0  # skew: now


def test_odometry_alone_is_the_pose_and_refuses_going_back_in_time() -> None:
    track = PoseTrack(localiser=False)
    assert track.latest() is None
    assert track.add_odometry(1.0, (1.0, 2.0, 0.5)) is None
    assert track.latest() == ((1.0, 2.0, 0.5), 1.0)
    rejected = track.add_odometry(0.5, (9.0, 9.0, 0.0))
    assert rejected is not None and rejected.reason == "out_of_order"
    assert track.latest() == ((1.0, 2.0, 0.5), 1.0)


@given(poses, st.lists(poses, min_size=2, max_size=20), st.floats(0, 1))
def test_localiser_correction_is_carried_forward_by_odometry(
    map_from_odom: tuple[float, float, float],
    odometry: list[tuple[float, float, float]],
    when: float,
) -> None:
    """If the localiser sees exactly T ∘ odometry, the track is T ∘ the latest odometry."""
    track = PoseTrack(localiser=True)
    for i, pose in enumerate(odometry):
        assert track.add_odometry(float(i), pose) is None
    assert track.latest() is None  # no localiser pose yet
    stamp = when * (len(odometry) - 1)
    at = track.odometry_at(stamp)
    assert at is not None
    assert track.add_localiser(stamp, compose(map_from_odom, at)) is None
    latest = track.latest()
    assert latest is not None and latest[1] == len(odometry) - 1
    assert close(latest[0], compose(map_from_odom, odometry[-1]), 1e-6)


def test_a_localiser_stamp_outside_the_odometry_history_is_refused() -> None:
    track = PoseTrack(localiser=True, history=3)
    for t in (1.0, 2.0, 3.0, 4.0):  # keeps 2, 3, 4
        track.add_odometry(t, (t, 0.0, 0.0))
    assert track.odometry_at(2.5) == pytest.approx((2.5, 0.0, 0.0))
    assert track.odometry_at(4.0 + MAX_LOCALISER_LEAD_S / 2) == (4.0, 0.0, 0.0)
    for stamp in (1.5, 4.0 + 2 * MAX_LOCALISER_LEAD_S):
        rejected = track.add_localiser(stamp, (0.0, 0.0, 0.0))
        assert rejected is not None and rejected.reason == "no_odometry"
    assert track.latest() is None


LIMITS = JumpLimits(top_speed=1.0, top_turn=7.4, slack_m=0.25, slack_rad=0.5)


@given(
    st.floats(-5, 5), st.floats(-5, 5), st.floats(-3, 3), st.floats(0.001, 0.1),
    st.floats(0, 1), st.floats(-1, 1),
)  # fmt: skip
def test_motion_the_robot_can_make_is_no_jump(
    x: float, y: float, t: float, dt: float, fraction: float, turn: float
) -> None:
    step = LIMITS.top_speed * dt * fraction
    pose = (x + step * math.cos(t), y + step * math.sin(t), wrap_angle(t + turn * dt))
    assume(math.hypot(pose[0], pose[1]) > RESET_RADIUS_M)
    assert odometry_jump((x, y, t), pose, dt, LIMITS) is None


def test_a_jump_or_a_reset_holds_until_a_localiser_pose_re_aligns() -> None:
    track = PoseTrack(localiser=False, jump=LIMITS)
    track.add_odometry(1.0, (2.0, 0.0, 0.0))
    track.add_odometry(1.02, (2.0, 1.0, 0.0))  # 1 m in 20 ms
    assert track.jumped is not None and "moved" in track.jumped
    reset = PoseTrack(localiser=True, jump=LIMITS)
    reset.add_odometry(1.0, (3.0, 0.0, 0.0))
    assert reset.add_localiser(1.0, (5.0, 5.0, 0.0)) is None
    reset.add_odometry(60.0, (0.0, 0.0, 0.0))  # back at the origin after a long silence
    assert reset.jumped is not None and "reset" in reset.jumped
    assert reset.add_localiser(59.0, (5.0, 5.0, 0.0)) is not None  # before the jump: no use
    assert reset.jumped is not None
    assert reset.add_localiser(60.0, (6.0, 5.0, 0.0)) is None
    assert reset.jumped is None
    latest = reset.latest()
    assert latest is not None and latest[0] == pytest.approx((6.0, 5.0, 0.0))


def test_a_clock_stepped_back_re_bases_instead_of_dropping_every_pose() -> None:
    track = PoseTrack(localiser=False, jump=LIMITS, clock_step_s=1.0)
    track.add_odometry(1000.0, (1.0, 0.0, 0.0), wall_now=1000.0)
    late = track.add_odometry(999.5, (1.0, 0.0, 0.0), wall_now=1000.01)
    assert late is not None and late.reason == "out_of_order"  # a late message, dropped
    stale = track.add_odometry(900.0, (1.0, 0.0, 0.0), wall_now=1000.02)
    assert stale is not None and stale.reason == "out_of_order"  # old, and far from now
    assert track.add_odometry(900.0, (1.01, 0.0, 0.0), wall_now=900.01) is None  # a step
    assert track.add_odometry(900.02, (1.02, 0.0, 0.0), wall_now=900.03) is None
    assert track.clock_steps == 1 and track.jumped is None
    latest = track.latest()
    assert latest is not None and latest == ((1.02, 0.0, 0.0), 900.02)
