"""CDR of the drive's messages: exact type hashes and payload bytes, decoding, bad payloads.

Oracles: literal RIHS01 hashes (rosbags' Jazzy typestore, as on a Jazzy robot), rosbags'
own serialisation, and the CDR layout packed by hand here (test-only) as a third opinion.
"""

from __future__ import annotations

import contextlib
import math
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_agent.drives.ros2_messages import (
    ODOMETRY,
    POSE_WITH_COVARIANCE_STAMPED,
    TWIST,
    TWIST_STAMPED,
    MalformedMessage,
    Ros2Messages,
    StampedPose,
    split_stamp,
    stamp_seconds,
    yaw_of,
)

JAZZY = Ros2Messages("jazzy")
CDR_LE = b"\x00\x01\x00\x00"  # encapsulation header: CDR, little-endian
finite = st.floats(-1e6, 1e6, allow_nan=False)


def test_type_hashes_are_the_jazzy_rihs01_hashes() -> None:
    assert JAZZY.type_hash(TWIST) == (
        "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"
    )
    assert JAZZY.type_hash(TWIST_STAMPED) == (
        "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64"
    )
    assert JAZZY.type_hash(ODOMETRY) == (
        "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0"
    )
    assert JAZZY.type_hash(POSE_WITH_COVARIANCE_STAMPED) == (
        "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e"
    )
    assert Ros2Messages("humble").type_hash(TWIST) == "TypeHashNotSupported"


def test_one_twist_payload_byte_for_byte() -> None:
    payload = JAZZY.encode_velocity(TWIST, 0.5, -0.25)
    t = JAZZY.store.types
    v = t["geometry_msgs/msg/Vector3"]
    rosbags = JAZZY.store.serialize_cdr(
        t[TWIST](linear=v(x=0.5, y=0.0, z=0.0), angular=v(x=0.0, y=0.0, z=-0.25)), TWIST
    )
    assert payload == bytes(rosbags)
    assert payload == CDR_LE + struct.pack("<6d", 0.5, 0.0, 0.0, 0.0, 0.0, -0.25)
    assert len(payload) == 52


def test_twist_stamped_carries_stamp_and_base_frame() -> None:
    payload = JAZZY.encode_velocity(
        TWIST_STAMPED, 0.2, 0.1, stamp_s=1700000000.25, frame_id="base_link"
    )
    # Header: sec int32, nanosec uint32, frame_id (uint32 length with NUL, bytes), pad to 8
    header = struct.pack("<iiI", 1700000000, 250_000_000, 10) + b"base_link\x00" + bytes(2)
    assert payload == CDR_LE + header + struct.pack("<6d", 0.2, 0, 0, 0, 0, 0.1)
    message = JAZZY.store.deserialize_cdr(payload, TWIST_STAMPED)
    assert message.header.frame_id == "base_link" and message.twist.angular.z == 0.1


def odometry_bytes(x: float, y: float, yaw: float, sec: int, nanosec: int, frame: str) -> bytes:
    """Our Odometry payload (robot at rest, child frame base_link, covariances 0)."""
    return JAZZY.encode_pose(ODOMETRY, StampedPose(x, y, yaw, stamp_seconds(sec, nanosec), frame))


def test_one_odometry_payload_byte_for_byte_and_decoded() -> None:
    yaw = 0.75
    t = JAZZY.store.types
    v, rest = t["geometry_msgs/msg/Vector3"], {"x": 0.0, "y": 0.0, "z": 0.0}
    by_rosbags = JAZZY.store.serialize_cdr(
        t[ODOMETRY](
            header=t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=1700000000, nanosec=250_000_000),
                frame_id="odom",
            ),
            child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=1.5, y=-2.0, z=0.0),
                    orientation=t["geometry_msgs/msg/Quaternion"](
                        x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                    ),
                ),
                covariance=np.zeros(36),
            ),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t[TWIST](linear=v(**rest), angular=v(**rest)), covariance=np.zeros(36)
            ),
        ),
        ODOMETRY,
    )
    payload = odometry_bytes(1.5, -2.0, yaw, 1700000000, 250_000_000, "odom")
    expected = (
        CDR_LE
        + struct.pack("<iiI", 1700000000, 250_000_000, 5) + b"odom\x00"  # header, ends at 17
        + bytes(3) + struct.pack("<I", 10) + b"base_link\x00"  # child frame, ends at 34
        + bytes(6)  # align the doubles to 8 (offset 40)
        + struct.pack("<3d4d", 1.5, -2.0, 0.0, 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        + bytes(36 * 8)  # pose covariance
        + bytes(6 * 8) + bytes(36 * 8)  # twist (at rest) and its covariance
    )  # fmt: skip
    assert payload == bytes(by_rosbags) == expected and len(payload) == 724
    pose = JAZZY.decode_pose(ODOMETRY, payload)
    assert (pose.x, pose.y, pose.frame_id) == (1.5, -2.0, "odom")
    assert pose.theta == pytest.approx(yaw, abs=1e-12)
    assert pose.stamp_s == 1700000000.25


def test_pose_with_covariance_stamped_round_trip() -> None:
    sent = StampedPose(x=3.0, y=4.0, theta=-2.5, stamp_s=12.5, frame_id="map")
    payload = JAZZY.encode_pose(POSE_WITH_COVARIANCE_STAMPED, sent)
    assert JAZZY.decode_pose(POSE_WITH_COVARIANCE_STAMPED, payload) == pytest.approx(sent)
    message = JAZZY.store.deserialize_cdr(payload, POSE_WITH_COVARIANCE_STAMPED)
    assert message.header.frame_id == "map" and message.pose.pose.position.x == 3.0
    with pytest.raises(ValueError, match="not a pose type"):
        JAZZY.encode_pose(TWIST, sent)


@pytest.mark.parametrize(
    "payload",
    [
        b"",
        CDR_LE,
        b"\x00\x00\x00\x00" + bytes(100),  # big-endian header, lengths nonsense
        CDR_LE + b"\xff" * 40,  # a string length of 4 GB
        odometry_bytes(1, 2, 0, 1, 0, "odom")[:100],  # truncated
    ],
)
def test_malformed_payloads_are_malformed_message(payload: bytes) -> None:
    with pytest.raises(MalformedMessage):
        JAZZY.decode_pose(ODOMETRY, payload)


def test_non_finite_or_degenerate_poses_are_malformed() -> None:
    with pytest.raises(MalformedMessage, match="non-finite"):
        JAZZY.decode_pose(ODOMETRY, odometry_bytes(math.nan, 0, 0, 1, 0, "odom"))
    good = bytearray(odometry_bytes(1, 2, 0, 1, 0, "odom"))
    good[68:100] = bytes(32)  # the orientation quaternion (4 + 64), all zero
    with pytest.raises(MalformedMessage, match="not a rotation"):
        JAZZY.decode_pose(ODOMETRY, bytes(good))


@given(st.binary(max_size=800))
def test_random_bytes_never_raise_anything_but_malformed(payload: bytes) -> None:
    with contextlib.suppress(MalformedMessage):
        JAZZY.decode_pose(ODOMETRY, payload)


@given(st.floats(-math.pi, math.pi, exclude_max=True), st.floats(1e-3, 1e3))
def test_yaw_of_a_planar_rotation_at_any_scale(yaw: float, scale: float) -> None:
    q = (0.0, 0.0, scale * math.sin(yaw / 2), scale * math.cos(yaw / 2))
    assert math.isclose(math.remainder(yaw_of(*q) - yaw, 2 * math.pi), 0.0, abs_tol=1e-9)


@given(st.floats(0, 4e9, allow_nan=False))
def test_stamps_split_into_sec_and_nanosec_and_back(stamp: float) -> None:
    sec, nanosec = split_stamp(stamp)
    assert 0 <= nanosec < 1_000_000_000
    assert stamp_seconds(sec, nanosec) == pytest.approx(stamp, abs=1e-6)


@given(finite, finite)
def test_velocities_round_trip_through_cdr(u: float, omega: float) -> None:
    message = JAZZY.store.deserialize_cdr(JAZZY.encode_velocity(TWIST, u, omega), TWIST)
    assert (message.linear.x, message.angular.z) == (u, omega)
