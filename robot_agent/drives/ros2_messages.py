"""ROS 2 messages of the ``ros2`` drive as CDR bytes, through rosbags (pure).

rmw_zenoh and zenoh-bridge-ros2dds both carry a message as CDR with its 4-byte
encapsulation header (``00 01 00 00``: little-endian CDR), exactly the bytes a DDS
writer sends (rmw_zenoh ``docs/design.md`` "Serialization/Deserialization"). rosbags'
typestore of the robot's distribution serialises and parses them, and gives the RIHS01
type hashes (REP-2011) rmw_zenoh puts in its keys.

Commands: ``geometry_msgs/msg/Twist`` or ``TwistStamped`` with the forward speed u [m/s]
in ``linear.x`` and the yaw rate omega [rad/s] (counter-clockwise) in ``angular.z``, in
the robot's base frame (REP-103). Poses: ``nav_msgs/msg/Odometry`` or
``geometry_msgs/msg/PoseWithCovarianceStamped``, reduced to the planar pose (x, y, yaw)
of the robot in the header's frame and the header's stamp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from rosbags.typesys import Stores, get_typestore

from robot_agent.drives.ros2_names import HUMBLE_TYPE_HASH

Distro = Literal["jazzy", "humble"]

TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
COMMAND_TYPES = (TWIST, TWIST_STAMPED)
POSE_TYPES = (ODOMETRY, POSE_WITH_COVARIANCE_STAMPED)

_STORES = {"jazzy": Stores.ROS2_JAZZY, "humble": Stores.ROS2_HUMBLE}


class MalformedMessage(ValueError):
    """A payload that is not a valid CDR message of the expected type."""


@dataclass(frozen=True)
class StampedPose:
    """A planar pose read from a message: x, y [m] and yaw [rad] of the robot in
    ``frame_id``, measured at ``stamp_s`` (ROS time: seconds since the Unix epoch; as a
    float64 it resolves ~0.24 us today, far below any staleness that matters). An
    Odometry's twist (in its child frame, the robot's base) gives ``u`` [m/s] and
    ``omega`` [rad/s], measured at the same stamp (NaN when the message has none)."""

    x: float
    y: float
    theta: float
    stamp_s: float
    frame_id: str
    u: float = math.nan
    omega: float = math.nan


def stamp_seconds(sec: int, nanosec: int) -> float:
    """``builtin_interfaces/Time`` as seconds."""
    return sec + nanosec * 1e-9


def split_stamp(stamp_s: float) -> tuple[int, int]:
    """Seconds as ``builtin_interfaces/Time`` (sec, nanosec), nanosec in [0, 1e9)."""
    sec = math.floor(stamp_s)
    nanosec = min(round((stamp_s - sec) * 1e9), 999_999_999)
    return int(sec), int(nanosec)


def yaw_of(x: float, y: float, z: float, w: float) -> float:
    """Yaw [rad] of quaternion (x, y, z, w), the rotation about z; any non-zero scale."""
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


class Ros2Messages:
    """CDR encoding and decoding of the drive's message types for one ROS 2 distribution."""

    def __init__(self, distro: Distro = "jazzy") -> None:
        self.distro = distro
        self.store = get_typestore(_STORES[distro])
        self._types: dict[str, Any] = self.store.types

    def type_hash(self, ros_type: str) -> str:
        """The type hash rmw_zenoh puts in keys: RIHS01 from Jazzy on, a placeholder in Humble."""
        if self.distro == "humble":
            return HUMBLE_TYPE_HASH
        return str(self.store.hash_rihs01(ros_type))

    def definition(self, ros_type: str) -> str:
        """The message definition text (with its dependencies), as ``ros2 interface show``."""
        return str(self.store.generate_msgdef(ros_type, ros_version=2)[0])

    def encode_velocity(
        self, ros_type: str, u: float, omega: float, *, stamp_s: float = 0.0, frame_id: str = ""
    ) -> bytes:
        """A Twist (or TwistStamped stamped ``stamp_s`` in ``frame_id``) commanding forward
        speed ``u`` [m/s] and yaw rate ``omega`` [rad/s]."""
        t = self._types
        vector = t["geometry_msgs/msg/Vector3"]
        twist = t[TWIST](linear=vector(x=u, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=omega))
        if ros_type == TWIST:
            message = twist
        elif ros_type == TWIST_STAMPED:
            sec, nanosec = split_stamp(stamp_s)
            header = t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame_id
            )
            message = t[TWIST_STAMPED](header=header, twist=twist)
        else:
            raise ValueError(f"not a velocity command type: {ros_type}")
        return bytes(self.store.serialize_cdr(message, ros_type))

    def encode_pose(
        self, ros_type: str, pose: StampedPose, child_frame_id: str = "base_link"
    ) -> bytes:
        """An Odometry (robot at rest, ``child_frame_id`` its base) or a
        PoseWithCovarianceStamped holding ``pose``; covariances zero."""
        t = self._types
        sec, nanosec = split_stamp(pose.stamp_s)
        header = t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=pose.frame_id
        )
        half = pose.theta / 2.0
        with_covariance = t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=pose.x, y=pose.y, z=0.0),
                orientation=t["geometry_msgs/msg/Quaternion"](
                    x=0.0, y=0.0, z=math.sin(half), w=math.cos(half)
                ),
            ),
            covariance=np.zeros(36),
        )
        if ros_type == POSE_WITH_COVARIANCE_STAMPED:
            message = t[ros_type](header=header, pose=with_covariance)
        elif ros_type == ODOMETRY:
            vector = t["geometry_msgs/msg/Vector3"]
            u = pose.u if math.isfinite(pose.u) else 0.0
            omega = pose.omega if math.isfinite(pose.omega) else 0.0
            twist = t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t[TWIST](
                    linear=vector(x=u, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=omega)
                ),
                covariance=np.zeros(36),
            )
            message = t[ros_type](
                header=header, child_frame_id=child_frame_id, pose=with_covariance, twist=twist
            )
        else:
            raise ValueError(f"not a pose type: {ros_type}")
        return bytes(self.store.serialize_cdr(message, ros_type))

    def decode_pose(self, ros_type: str, payload: bytes) -> StampedPose:
        """The robot's planar pose in an Odometry or PoseWithCovarianceStamped payload.

        Raises :class:`MalformedMessage` when the bytes are not such a message or the
        pose is not finite (or its orientation is no rotation)."""
        if ros_type not in POSE_TYPES:
            raise ValueError(f"not a pose type: {ros_type}")
        try:
            message: Any = self.store.deserialize_cdr(payload, ros_type)
        except Exception as exc:  # rosbags raises SerdeError, or struct/Unicode errors
            raise MalformedMessage(f"{ros_type}: {exc}") from exc
        pose = message.pose.pose  # PoseWithCovariance.pose in both types
        p, q = pose.position, pose.orientation
        values = (p.x, p.y, q.x, q.y, q.z, q.w)
        if not all(math.isfinite(v) for v in values):
            raise MalformedMessage(f"{ros_type}: non-finite pose {values}")
        if q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w < 1e-6:
            raise MalformedMessage(f"{ros_type}: orientation is not a rotation {values[2:]}")
        stamp = message.header.stamp
        u = omega = math.nan
        if ros_type == ODOMETRY:  # the measured velocity, in the robot's base frame
            twist = message.twist.twist
            u, omega = float(twist.linear.x), float(twist.angular.z)
        return StampedPose(
            x=float(p.x),
            y=float(p.y),
            theta=yaw_of(q.x, q.y, q.z, q.w),
            stamp_s=stamp_seconds(stamp.sec, stamp.nanosec),
            frame_id=str(message.header.frame_id),
            u=u,
            omega=omega,
        )
