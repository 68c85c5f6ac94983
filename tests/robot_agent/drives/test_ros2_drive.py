"""``Ros2Drive`` on real Zenoh over loopback, a plain Zenoh session playing the robot.

Exact keys, payloads and attachments of the commands; poses with their stamps on the
agent's clock; every kind of bad input dropped and counted; the ROS-graph tokens; the
factory ``--drive ros2`` and its clear errors. The drive's clocks are injected so stamps
are exact; waits poll conditions (``support.wait_for``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
import zenoh
import zenoh.ext
from support import wait_for
from zenoh_ros2_sdk.discovery import _parse_liveliness_keyexpr

from fleet.cli.agent import DRIVES, load_drive
from fleet.core.control import body_velocities
from fleet.core.wire import Pose
from fleet.io.settings import Ros2Settings, Settings, load_settings
from fleet.io.transport import open_session, zenoh_config
from robot_agent.drives.ros2 import ZERO_REPEATS, Ros2Drive, robot_session_settings
from robot_agent.drives.ros2_attachment import decode_attachment, entity_gid
from robot_agent.drives.ros2_messages import (
    ODOMETRY,
    POSE_WITH_COVARIANCE_STAMPED,
    TWIST,
    TWIST_STAMPED,
    Ros2Messages,
    StampedPose,
    split_stamp,
)

pytestmark = pytest.mark.integration

MESSAGES = Ros2Messages("jazzy")
WALL = 1_700_000_000.0  # the drive's wall clock [s since the epoch]
MONO = 5_000.0  # the drive's monotonic clock [s]
TWIST_KEY = "0/cmd_vel/geometry_msgs::msg::dds_::Twist_/" + MESSAGES.type_hash(TWIST)
ODOM_KEY = "0/odom/nav_msgs::msg::dds_::Odometry_/" + MESSAGES.type_hash(ODOMETRY)


def pose_message(
    ros_type: str, x: float, y: float, yaw: float, stamp: float, frame: str = "odom"
) -> bytes:
    """An Odometry or PoseWithCovarianceStamped payload."""
    return MESSAGES.encode_pose(ros_type, StampedPose(x, y, yaw, stamp, frame))


@dataclass
class Robot:
    """The robot side: puts poses, records every command (key, payload, attachment)."""

    session: Any
    commands: list[tuple[str, bytes, bytes | None]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    publishers: dict[str, Any] = field(default_factory=dict)

    def on_command(self, sample: Any) -> None:
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        with self.lock:
            self.commands.append((str(sample.key_expr), sample.payload.to_bytes(), attachment))

    def received(self) -> list[tuple[str, bytes, bytes | None]]:
        with self.lock:
            return list(self.commands)

    def put(self, key: str, payload: bytes) -> None:
        """Publish once a subscriber (the drive's) matches ``key``: Zenoh drops a sample
        put before the subscription has reached the router."""
        publisher = self.publishers.get(key)
        if publisher is None:
            publisher = self.session.declare_publisher(
                key, congestion_control=zenoh.CongestionControl.BLOCK
            )
            self.publishers[key] = publisher
            wait_for(lambda: publisher.matching_status.matching, 10, f"a subscriber of {key}")
        publisher.put(payload)

    def close(self) -> None:
        for publisher in self.publishers.values():
            publisher.undeclare()


@pytest.fixture
def robot(client_settings: Settings) -> Iterator[Robot]:
    with open_session(client_settings, "client") as session:
        robot = Robot(session)
        subscriber = session.declare_subscriber("**/cmd_vel/**", robot.on_command)
        try:
            yield robot
        finally:
            robot.close()
            subscriber.undeclare()


@pytest.fixture
def drive_session(client_settings: Settings) -> Iterator[Any]:
    with open_session(client_settings, "client") as session:
        yield session


def make(session: Any, **config: Any) -> Ros2Drive:
    return Ros2Drive(
        session,
        Ros2Settings(**config),
        load_settings().profile,
        node_name="parkfleet_r1",
        monotonic=lambda: MONO,
        wall_clock=lambda: WALL,
    )


def velocity(ros_type: str, payload: bytes) -> tuple[float, float]:
    message = MESSAGES.store.deserialize_cdr(payload, ros_type)
    twist = message if ros_type == TWIST else message.twist
    return (twist.linear.x, twist.angular.z)


def test_a_held_robot_gets_a_zero_every_tick(robot: Robot, drive_session: Any) -> None:
    """stop() (e-stop, pause, holding ...) never falls silent, so a teleop is overridden."""
    drive = make(drive_session)
    try:
        wait_for(lambda: drive.cmd_vel_subscribed, 10, "the robot's cmd_vel subscriber")
        for _ in range(3 * ZERO_REPEATS):
            drive.stop()
        wait_for(lambda: len(robot.received()) >= 3 * ZERO_REPEATS, 10, "zeros")
        assert {velocity(TWIST, p) for _, p, _ in robot.received()} == {(0.0, 0.0)}
    finally:
        drive.close()


def test_commands_go_out_on_the_exact_key_with_the_attachment(
    robot: Robot, drive_session: Any
) -> None:
    drive = make(drive_session)
    try:
        wait_for(lambda: drive.cmd_vel_subscribed, 10, "the robot's cmd_vel subscriber")
        drive.stop()  # a zero first: the robot may be moving when the agent starts
        first = 1
        drive.command_wheels(10.0, 6.0)
        for _ in range(3 * ZERO_REPEATS):
            drive.release()  # idle: zeros after motion, then silence...
        drive.command_wheels(-4.0, 4.0)  # ...until the next motion (a marker here)
        wait_for(lambda: len(robot.received()) >= first + ZERO_REPEATS + 2, 10, "commands")
        assert velocity(TWIST, robot.received()[0][1]) == (0.0, 0.0)
        sent = robot.received()[first:]
        profile = load_settings().profile
        expected = [
            body_velocities(10.0, 6.0, profile.wheel_radius, profile.half_axle),
            *[(0.0, 0.0)] * ZERO_REPEATS,
            body_velocities(-4.0, 4.0, profile.wheel_radius, profile.half_axle),
        ]
        assert [velocity(TWIST, payload) for _, payload, _ in sent] == [
            (float(u), float(w)) for u, w in expected
        ]
        assert {key for key, _, _ in sent} == {TWIST_KEY}
        attachments = [decode_attachment(a) for _, _, a in robot.received() if a is not None]
        assert len(attachments) == len(robot.received())  # every message has one
        assert [a.sequence_number for a in attachments] == list(range(1, len(attachments) + 1))
        assert {a.source_timestamp_ns for a in attachments} == {round(WALL * 1e9)}
        assert {a.gid for a in attachments} == {entity_gid(drive.tokens[1])}
    finally:
        drive.close()


def test_pose_in_the_world_frame_stamped_on_the_agent_clock(
    robot: Robot, drive_session: Any
) -> None:
    drive = make(drive_session, origin=(1.0, 2.0, math.pi / 2))
    try:
        with pytest.raises(RuntimeError, match="no pose"):
            drive.read_pose()
        robot.put(ODOM_KEY, pose_message(ODOMETRY, 1.0, 0.0, 0.25, WALL - 0.3))
        wait_for(lambda: drive.poses_received == 1, 10, "the odometry")
        pose, stamp = drive.read_pose()
        assert stamp == pytest.approx(MONO - 0.3)  # measured 0.3 s before "now"
        assert pose.x == pytest.approx(1.0) and pose.y == pytest.approx(3.0)
        assert pose.theta == pytest.approx(math.pi / 2 + 0.25)
        drive.wait_for_pose(0.0)  # already there
    finally:
        drive.close()


def test_bad_input_is_dropped_counted_and_the_last_good_pose_kept(
    robot: Robot, drive_session: Any
) -> None:
    drive = make(drive_session)
    try:
        robot.put(ODOM_KEY, pose_message(ODOMETRY, 1.0, 2.0, 0.0, WALL - 0.1))
        wait_for(lambda: drive.poses_received == 1, 10, "a good pose")
        good = drive.read_pose()
        odometry_type = "nav_msgs::msg::dds_::Odometry_"
        bad = [
            (ODOM_KEY, b"\x00\x01\x00\x00 not an odometry", "malformed"),
            (ODOM_KEY, pose_message(ODOMETRY, math.inf, 0, 0, WALL), "malformed"),
            (ODOM_KEY, pose_message(ODOMETRY, 5, 5, 0, WALL, frame="map"), "wrong_frame"),
            (ODOM_KEY, pose_message(ODOMETRY, 5, 5, 0, WALL + 5.0), "future_stamp"),
            (ODOM_KEY, pose_message(ODOMETRY, 5, 5, 0, 0.0), "unstamped"),
            (ODOM_KEY, pose_message(ODOMETRY, 5, 5, 0, WALL - 1.0), "out_of_order"),
            (ODOM_KEY, b"\x00\x01\x00\x00" + bytes(70_000), "oversized"),
            ("0/odom/geometry_msgs::msg::dds_::PoseStamped_/RIHS01_x", b"x", "unknown_type"),
            (f"0/odom/{odometry_type}/TypeHashNotSupported", b"x", "type_hash_mismatch"),
        ]
        for key, payload, _ in bad:
            robot.put(key, payload)
        wait_for(lambda: drive.decoder.dropped_total == len(bad), 10, "every bad message dropped")
        counts: dict[str, int] = {}
        for _, _, reason in bad:
            counts[reason] = counts.get(reason, 0) + 1
        assert dict(drive.decoder.dropped) == counts
        assert drive.read_pose() == good and drive.poses_received == 1
        assert drive.guard.errors == 0
        robot.put(ODOM_KEY, pose_message(ODOMETRY, 3.0, 4.0, 0.0, WALL))  # still listening
        wait_for(lambda: drive.poses_received == 2, 10, "the next good pose")
        assert drive.read_pose()[0] == Pose(x=3.0, y=4.0, theta=0.0)
    finally:
        drive.close()


def test_bridge_mapping_with_stamped_commands(robot: Robot, drive_session: Any) -> None:
    drive = make(
        drive_session,
        key_mapping="bridge",
        namespace="/tb4_1",
        cmd_vel_topic="/cmd_vel",
        cmd_vel_type=TWIST_STAMPED,
    )
    try:
        assert (drive.cmd_vel.key, drive.odometry.subscription) == ("tb4_1/cmd_vel", "tb4_1/odom")
        assert drive.tokens == []  # the bridge makes the DDS side's graph
        drive.command_wheels(8.0, 8.0)
        wait_for(lambda: any(a for a in robot.received()), 10, "the command")
        key, payload, attachment = robot.received()[-1]
        assert (key, attachment) == ("tb4_1/cmd_vel", None)
        message = MESSAGES.store.deserialize_cdr(payload, TWIST_STAMPED)
        assert message.header.frame_id == "base_link"
        assert (message.header.stamp.sec, message.header.stamp.nanosec) == split_stamp(WALL)
        assert velocity(TWIST_STAMPED, payload) == (0.4, 0.0)
        robot.put("tb4_1/odom", pose_message(ODOMETRY, 1.0, 1.0, 0.0, WALL))
        wait_for(lambda: drive.poses_received == 1, 10, "odometry through the bridge key")
    finally:
        drive.close()


def test_localiser_pose_is_carried_forward_by_odometry(robot: Robot, drive_session: Any) -> None:
    drive = make(drive_session, pose_source="localiser", namespace="/tb4_1", odom_jump_m=5.0)
    assert drive.localiser is not None
    amcl_key = drive.localiser.key
    assert amcl_key == "0/tb4_1/amcl_pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/" + (
        MESSAGES.type_hash(POSE_WITH_COVARIANCE_STAMPED)
    )
    odom_key = drive.odometry.key
    try:
        robot.put(odom_key, pose_message(ODOMETRY, 0.0, 0.0, 0.0, WALL - 1.0))
        robot.put(odom_key, pose_message(ODOMETRY, 1.0, 0.0, 0.0, WALL - 0.5))
        wait_for(lambda: drive.poses_received == 2, 10, "odometry")
        assert not drive._has_pose.is_set()  # no localiser pose yet: no usable pose
        # the localiser saw the robot at (10, 5) facing +y when odometry said (0.5, 0, 0)
        robot.put(amcl_key, pose_message(POSE_WITH_COVARIANCE_STAMPED, 10, 5, math.pi / 2,
                                         WALL - 0.75, frame="map"))  # fmt: skip
        wait_for(lambda: drive.poses_received == 3, 10, "the localiser pose")
        robot.put(odom_key, pose_message(ODOMETRY, 2.0, 0.0, 0.0, WALL - 0.2))  # 1.5 m on
        wait_for(lambda: drive.poses_received == 4, 10, "more odometry")
        pose, stamp = drive.read_pose()
        assert (pose.x, pose.y, pose.theta) == pytest.approx((10.0, 6.5, math.pi / 2))
        assert stamp == pytest.approx(MONO - 0.2)  # the odometry's stamp
    finally:
        drive.close()


def test_the_drive_is_a_node_of_the_ros_graph_until_closed(
    drive_session: Any, client_settings: Settings
) -> None:
    drive = make(drive_session, namespace="/tb4_1")
    with open_session(client_settings, "client") as observer:

        def tokens() -> list[str]:
            return sorted(str(r.ok.key_expr) for r in observer.liveliness().get("@ros2_lv/0/**"))

        try:
            wait_for(lambda: len(tokens()) == 3, 10, "node, publisher and subscription tokens")
            zid = str(drive_session.info.zid())
            assert f"@ros2_lv/0/{zid}/0/0/NN/%/%tb4_1/parkfleet_r1" in tokens()
            endpoints = [_parse_liveliness_keyexpr(t) for t in tokens() if "/NN/" not in t]
            assert {(e["kind"], e["qualified_name"], e["dds_type"]) for e in endpoints if e} == {
                ("MP", "/tb4_1/cmd_vel", "geometry_msgs::msg::dds_::Twist_"),
                ("MS", "/tb4_1/odom", "nav_msgs::msg::dds_::Odometry_"),
            }
        finally:
            drive.close()
        wait_for(lambda: tokens() == [], 10, "the tokens to go")


def test_ros2_is_a_named_drive_that_waits_for_the_first_pose(
    client_settings: Settings, robot: Robot
) -> None:
    assert DRIVES["ros2"] == "robot_agent.drives.ros2:make_drive"
    settings = client_settings.model_copy(
        update={"robot_id": "tb4-1", "ros2": Ros2Settings(first_pose_timeout_s=0.5)}
    )
    with pytest.raises(ConnectionError, match=r"no usable pose .* nav_msgs/msg/Odometry on 0/odom"):
        load_drive("ros2", settings)
    done = threading.Event()

    def publish_odometry() -> None:  # a robot that is already running
        while not done.wait(0.02):
            robot.put(ODOM_KEY, pose_message(ODOMETRY, 1.0, 2.0, 0.0, time.time()))

    publisher = threading.Thread(target=publish_odometry)
    publisher.start()
    try:
        drive = load_drive("ros2", settings.model_copy(update={"ros2": Ros2Settings()}))
        assert isinstance(drive, Ros2Drive) and drive.node_name == "parkfleet_tb4_1"
        assert drive.read_pose()[0] == Pose(x=1.0, y=2.0, theta=0.0)
        drive.close()
    finally:
        done.set()
        publisher.join()


def test_no_robot_router_is_a_clear_error() -> None:
    settings = load_settings(ros2={"connect": ["tcp/127.0.0.1:9"]}, robot_id="r1")
    with pytest.raises(ConnectionError, match="cannot reach the robot's Zenoh router"):
        load_drive("ros2", settings)


def test_the_robot_router_session_leaves_the_fleet_security_out(tmp_path: Any) -> None:
    for name in ("ca.pem", "me.pem", "me.key"):
        (tmp_path / name).write_text("x")
    fleet = load_settings(
        connect=["tls/fleet:7447"],
        tls_root_ca=tmp_path / "ca.pem",
        tls_cert=tmp_path / "me.pem",
        tls_key=tmp_path / "me.key",
        zenoh_user="r1",
        zenoh_password="secret",
    )
    assert robot_session_settings(fleet) is fleet  # no ros2.connect: the agent's own link
    robot = robot_session_settings(
        fleet.model_copy(update={"ros2": Ros2Settings(connect=["tcp/127.0.0.1:7447"])})
    )
    assert robot.connect == ["tcp/127.0.0.1:7447"] and robot.zenoh_mode == "client"
    assert (robot.tls_root_ca, robot.tls_cert, robot.zenoh_user) == (None, None, None)


def test_a_latched_localiser_pose_published_before_the_drive_arrives(
    robot: Robot, drive_session: Any, client_settings: Settings
) -> None:
    """AMCL's amcl_pose is transient-local: under rmw_zenoh an AdvancedPublisher with a cache.
    Its pose, put before the drive subscribes, still reaches the drive (history)."""
    amcl_key = "0/amcl_pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/" + (
        MESSAGES.type_hash(POSE_WITH_COVARIANCE_STAMPED)
    )
    config = zenoh_config(client_settings, "client")
    config.insert_json5("timestamping/enabled", "true")  # as rmw_zenoh's session config has
    with zenoh.open(config) as amcl:
        _latched_pose_reaches_the_drive(amcl, amcl_key, robot, drive_session)


def _latched_pose_reaches_the_drive(
    amcl: Any, amcl_key: str, robot: Robot, drive_session: Any
) -> None:
    publisher = zenoh.ext.declare_advanced_publisher(
        amcl, amcl_key, cache=zenoh.ext.CacheConfig(1), publisher_detection=True
    )
    try:
        publisher.put(pose_message(POSE_WITH_COVARIANCE_STAMPED, 3, 4, 0.0, WALL - 0.1, "map"))
        drive = make(drive_session, pose_source="localiser")
        try:
            robot.put(drive.odometry.key, pose_message(ODOMETRY, 0.0, 0.0, 0.0, WALL - 0.1))
            wait_for(drive._has_pose.is_set, 10, "the latched localiser pose")
            pose, _ = drive.read_pose()
            assert (pose.x, pose.y) == pytest.approx((3.0, 4.0))
            assert any(":1:," in token for token in drive.tokens)  # announced transient-local
        finally:
            drive.close()
    finally:
        publisher.undeclare()


def test_the_odometry_s_twist_is_the_measured_wheel_speeds(
    robot: Robot, drive_session: Any
) -> None:
    """The latency estimator's input: the robot's measured (u, omega) as wheel speeds (Eq. 2)
    at the odometry's stamp on the agent's clock; nothing before the first odometry."""
    drive = make(drive_session)
    try:
        assert all(math.isnan(v) for v in drive.wheel_speeds())
        moving = StampedPose(1.0, 0.0, 0.25, WALL - 0.1, "odom", u=0.5, omega=1.0)
        robot.put(ODOM_KEY, MESSAGES.encode_pose(ODOMETRY, moving))
        wait_for(lambda: drive.poses_received == 1, 10, "the odometry")
        right, left, at = drive.wheel_speeds()
        r, b = drive.profile.wheel_radius, drive.profile.half_axle
        assert right == pytest.approx((0.5 + b * 1.0) / r)
        assert left == pytest.approx((0.5 - b * 1.0) / r)
        assert at == pytest.approx(MONO - 0.1)
    finally:
        drive.close()
