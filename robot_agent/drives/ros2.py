"""The ``ros2`` drive: ``parkfleet agent --drive ros2`` drives a ROS 2 robot over Zenoh.

The fleet side needs no ROS installation: the drive speaks the ROS 2 wire format itself.

* **Commands** -- the agent's wheel speeds become (u, omega) again by Eq. (2)
  (:func:`fleet.core.control.body_velocities`) and go out as ``geometry_msgs/msg/Twist``
  (or ``TwistStamped``, ``Ros2Settings.cmd_vel_type``) on the robot's ``cmd_vel``, one
  per control tick (50 Hz). While the agent holds the robot stopped for a reason
  (:meth:`Ros2Drive.stop`: e-stop, pause, holding, link lost, pose stale or jumped,
  waiting) a zero goes out every tick, so a teleop or Nav2 on the same ``cmd_vel`` is
  overridden at the control rate. When the robot merely stands with nothing to do (idle or
  arrived, :meth:`Ros2Drive.release`) the zero is sent :data:`ZERO_REPEATS` times after
  motion, then the drive falls silent so an operator may teleop it. This is **not** a
  hardware stop (docs/robots.md "Where the two links go").
* **Measured wheels** -- :meth:`Ros2Drive.wheel_speeds`: the odometry's twist (the
  robot's measured u and omega) as wheel speeds by Eq. (2), at the odometry's stamp: the
  agent learns the robot's command-to-wheel latency from it (``robot_agent.latency``).
* **Pose** -- ``nav_msgs/msg/Odometry`` on ``odom`` or a localiser's
  ``geometry_msgs/msg/PoseWithCovarianceStamped`` (e.g. ``amcl_pose``) carried forward
  by the odometry (:mod:`robot_agent.drives.ros2_pose`), moved into the fleet's world
  frame by ``Ros2Settings.origin``. :meth:`Ros2Drive.read_pose` reports the time the
  message's own header stamp maps to on this computer's monotonic clock, so the agent's
  staleness check (``pose_stale_s``) stops the robot when the odometry stops. An odometry
  jump or reset is reported by :meth:`Ros2Drive.faults` (``pose_jump``: the agent holds)
  until re-aligned; a clock stepped back re-bases the track (``ros2_pose``). The localiser
  is subscribed transient-local (a Zenoh advanced subscriber with history), so AMCL's
  latched last pose arrives even when it was published before the agent started.
* **Bad input** -- a message of another type or type hash, malformed CDR, a non-finite
  pose, a wrong frame, a missing or future stamp: dropped, counted by reason in
  :attr:`Ros2Drive.decoder` and logged (sampled); never raised into the agent. The robot
  holds when its last good pose goes stale.
* **Wire** -- rmw_zenoh keys, attachment and graph liveliness tokens (the agent shows in
  ``ros2 node list`` as ``parkfleet_<robot id>``), or the zenoh-bridge-ros2dds keys
  (:mod:`~robot_agent.drives.ros2_names`, :mod:`~robot_agent.drives.ros2_attachment`,
  :mod:`~robot_agent.drives.ros2_messages`).

**Session.** The drive opens its own Zenoh client session: to ``Ros2Settings.connect``
(the robot's own router, usually ``tcp/127.0.0.1:7447`` on the robot computer, with no
fleet TLS or credentials), or, when that is empty, to the agent's endpoints with the
agent's security settings (the robot's router meshed with the fleet's). Its own session
because the factory runs before the agent's session exists, and because the two links
fail apart: when the fleet link is cut the agent holds, and the drive still reaches the
robot to stop it. :meth:`Ros2Drive.close` (called by ``parkfleet agent`` on exit)
undeclares everything and closes that session.

Followed (learned from, no code copied), in github.com/ros2/rmw_zenoh (``rolling``,
2025): ``docs/design.md`` (key expressions, graph cache tokens, publishers' attachment,
QoS); ``rmw_zenoh_cpp/src/detail/liveliness_utils.cpp`` (token layout, name mangling,
``qos_to_keyexpr``), ``attachment_helpers.cpp`` (attachment serialisation),
``rmw_publisher_data.cpp`` (sequence numbers from 1, source timestamps, congestion
control), ``rmw_subscription_data.cpp`` (samples without an attachment are dropped),
``qos.cpp`` (QoS defaults); and zenoh-plugin-ros2dds ``DEFAULT_CONFIG.json5``
(``namespace``: the bridge's key mapping).
"""

from __future__ import annotations

import logging
import math
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh
import zenoh.ext

from fleet.core.control import body_velocities
from fleet.core.params import RobotProfile
from fleet.core.step import wheel_speeds
from fleet.core.wire import MAX_PAYLOAD_BYTES, Pose, Rejected
from fleet.io.decoder import CallbackGuard, Decoder
from fleet.io.settings import RobotSettings, Ros2Settings
from fleet.io.transport import zenoh_config
from robot_agent.drive import PoseReading
from robot_agent.drives.ros2_attachment import Attachment, encode_attachment, entity_gid
from robot_agent.drives.ros2_messages import (
    ODOMETRY,
    POSE_WITH_COVARIANCE_STAMPED,
    MalformedMessage,
    Ros2Messages,
    StampedPose,
)
from robot_agent.drives.ros2_names import (
    EntityKind,
    any_type_key,
    data_key,
    dds_type_name,
    endpoint_token,
    fully_qualified,
    key_type,
    node_token,
    qos_token,
    topic_path,
)
from robot_agent.drives.ros2_pose import (
    JumpLimits,
    PoseTrack,
    check_pose,
    compose,
    measured_at,
)

_log = logging.getLogger(__name__)

#: Zero commands sent after motion before an idle drive falls silent (100 ms at 50 Hz).
ZERO_REPEATS = 5
#: History depth of the localiser subscription (AMCL: transient-local, keep last 1).
LOCALISER_DEPTH = 1
#: Security settings a session to the robot's own router does not inherit from the fleet.
_FLEET_ONLY: dict[str, object] = {
    "listen": [],
    "zenoh_mode": "client",
    "zenoh_user": None,
    "zenoh_password": None,
    "zenoh_credentials_file": None,
    "tls_root_ca": None,
    "tls_cert": None,
    "tls_key": None,
}  # (a client session applies no access control: that is a router's, fleet.io.transport)


def default_node_name(robot_id: str | None) -> str:
    """``parkfleet_<robot id>`` with the characters ROS forbids in node names as ``_``."""
    return "parkfleet" if robot_id is None else "parkfleet_" + re.sub(r"\W", "_", robot_id)


@dataclass(frozen=True)
class Ros2Topic:
    """One topic of the drive as it appears on Zenoh."""

    name: str  # fully qualified ROS name, e.g. /tb4_1/odom
    ros_type: str  # e.g. nav_msgs/msg/Odometry
    type_hash: str  # RIHS01_… (Humble: TypeHashNotSupported)
    path: str  # its key chunks (mapping-dependent)
    key: str  # the data key of this type
    subscription: str  # the key subscribed to (any type of this topic)


class Ros2Drive:
    """A ROS 2 robot behind the :class:`~robot_agent.drive.Drive` interface (module docstring).

    ``session`` is the Zenoh session on the robot's side; closed by :meth:`close` when
    ``owns_session``. ``monotonic`` and ``wall_clock`` are the clocks [s] of staleness
    and of ROS stamps.
    """

    def __init__(
        self,
        session: Any,
        config: Ros2Settings,
        profile: RobotProfile,
        *,
        node_name: str = "parkfleet",
        owns_session: bool = False,
        monotonic: Callable[[], float] = time.monotonic,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        self.config = config
        self.profile = profile
        self.node_name = node_name
        self.messages = Ros2Messages(config.distro)
        self.decoder = Decoder(f"ros2 drive {node_name}")
        self.guard = CallbackGuard(f"ros2 drive {node_name}")
        self._session = session
        self._owns_session = owns_session
        self._monotonic = monotonic
        self._wall = wall_clock
        self._lock = threading.Lock()
        top_speed = profile.max_wheel_speed * profile.wheel_radius  # [m/s], Eq. (2)
        self._track = PoseTrack(
            localiser=config.pose_source == "localiser",
            jump=JumpLimits(
                top_speed=top_speed,
                top_turn=top_speed / profile.half_axle,
                slack_m=config.odom_jump_m,
                slack_rad=config.odom_jump_rad,
            ),
            clock_step_s=config.clock_step_s,
        )
        self._odometry_measured = float("-inf")  # [s, monotonic] of the newest odometry
        #: The newest odometry's twist as (right, left) wheel speeds [rad/s] and its time.
        self._wheels: tuple[float, float, float] = (math.nan, math.nan, math.nan)
        self._reading: PoseReading | None = None
        self._has_pose = threading.Event()
        self._sequence = 1  # rmw_zenoh numbers a publisher's messages from 1
        self._zeros_left = ZERO_REPEATS  # a zero goes out first: the robot may be moving
        self._handles: list[Any] = []
        self._closed = False
        self.poses_received = 0
        self.commands_sent = 0
        self.last_command: tuple[float, float] | None = None  # (u [m/s], omega [rad/s])
        self.cmd_vel = self._topic(config.cmd_vel_topic, config.cmd_vel_type)
        self.odometry = self._topic(config.odom_topic, ODOMETRY)
        self.localiser = (
            self._topic(config.localiser_topic, POSE_WITH_COVARIANCE_STAMPED)
            if config.pose_source == "localiser"
            else None
        )
        self.tokens: list[str] = []  # graph liveliness tokens declared (rmw_zenoh only)
        self._gid = bytes(16)
        try:
            self._declare()
        except BaseException:
            self.close()
            raise

    # -- declarations -----------------------------------------------------------------------
    def _topic(self, name: str, ros_type: str) -> Ros2Topic:
        c = self.config
        path = topic_path(c.key_mapping, name, c.namespace)
        type_hash = self.messages.type_hash(ros_type)
        return Ros2Topic(
            name=fully_qualified(name, c.namespace),
            ros_type=ros_type,
            type_hash=type_hash,
            path=path,
            key=data_key(c.key_mapping, c.domain_id, path, ros_type, type_hash),
            subscription=any_type_key(c.key_mapping, c.domain_id, path),
        )

    def _token(self, kind: EntityKind, entity_id: int, topic: Ros2Topic, qos: str) -> str:
        c = self.config
        return endpoint_token(
            kind,
            domain_id=c.domain_id,
            zid=str(self._session.info.zid()),
            node_id=0,
            entity_id=entity_id,
            namespace=c.namespace,
            node_name=self.node_name,
            topic=topic.name,
            ros_type=topic.ros_type,
            type_hash=topic.type_hash,
            qos=qos,
        )

    def _declare(self) -> None:
        c, session = self.config, self._session
        rmw = c.key_mapping == "rmw_zenoh"
        publisher = session.declare_publisher(
            self.cmd_vel.key, encoding=zenoh.Encoding.APPLICATION_CDR
        )
        self._handles.append(publisher)
        self._publisher = publisher
        subscriptions: list[tuple[Ros2Topic, Callable[[Any], None]]] = [
            (self.odometry, self._on_odometry)
        ]
        if self.localiser is not None:
            subscriptions.append((self.localiser, self._on_localiser))
        for topic, callback in subscriptions:
            if topic is self.localiser:
                # AMCL publishes amcl_pose transient-local: rmw_zenoh gives such a publisher
                # an AdvancedPublisher with a cache; history fetches its last pose, also from
                # a publisher that appears later (detect_late_publishers).
                handle: Any = zenoh.ext.declare_advanced_subscriber(
                    session,
                    topic.subscription,
                    self.guard.wrap(callback),
                    history=zenoh.ext.HistoryConfig(
                        detect_late_publishers=True, max_samples=LOCALISER_DEPTH
                    ),
                    subscriber_detection=True,
                )
            else:
                handle = session.declare_subscriber(topic.subscription, self.guard.wrap(callback))
            self._handles.append(handle)
        if rmw:  # the ROS graph: node, publisher (reliable), subscriptions (best effort)
            zid = str(session.info.zid())
            self.tokens.append(node_token(c.domain_id, zid, 0, c.namespace, self.node_name))
            self.tokens.append(
                self._token("MP", 1, self.cmd_vel, qos_token(reliable=True, depth=1))
            )
            for entity_id, (topic, _) in enumerate(subscriptions, start=2):
                qos = (
                    qos_token(reliable=True, depth=LOCALISER_DEPTH, transient_local=True)
                    if topic is self.localiser
                    else qos_token(reliable=False, depth=5)
                )
                self.tokens.append(self._token("MS", entity_id, topic, qos))
            self._gid = entity_gid(self.tokens[1])
            liveliness = session.liveliness()
            for token in self.tokens:
                self._handles.append(liveliness.declare_token(token))
        _log.info(
            "ros2 drive %s: %s on %s, pose from %s%s",
            self.node_name,
            c.cmd_vel_type,
            self.cmd_vel.key,
            self.odometry.subscription,
            f" and {self.localiser.subscription}" if self.localiser is not None else "",
        )

    # -- incoming poses ---------------------------------------------------------------------
    def _decode(self, sample: Any, topic: Ros2Topic) -> StampedPose | None:
        key = str(sample.key_expr)
        c = self.config
        announced = key_type(c.key_mapping, key, c.domain_id, topic.path)
        if announced is not None and announced != (dds_type_name(topic.ros_type), topic.type_hash):
            if announced[0] != dds_type_name(topic.ros_type):
                self.decoder.drop("unknown_type", f"{key}: expected {topic.ros_type}")
            else:
                self.decoder.drop(
                    "type_hash_mismatch",
                    f"{key}: expected {topic.type_hash} (is ros2.distro = {c.distro!r} right?)",
                )
            return None
        payload = bytes(sample.payload.to_bytes())
        if len(payload) > MAX_PAYLOAD_BYTES:
            self.decoder.drop("oversized", f"{len(payload)} bytes on {key}")
            return None
        try:
            return self.messages.decode_pose(topic.ros_type, payload)
        except MalformedMessage as exc:
            self.decoder.drop("malformed", f"{key}: {exc}")
            return None

    def _accept(self, sample: Any, topic: Ros2Topic, frame: str) -> StampedPose | None:
        """The sample's pose if it may be used, else None (dropped and counted)."""
        pose = self._decode(sample, topic)
        if pose is None:
            return None
        rejected = check_pose(pose, frame, self._wall(), self.config.max_future_s)
        if rejected is not None:
            self.decoder.drop(rejected.reason, f"{topic.name}: {rejected.detail}")
            return None
        return pose

    def _on_odometry(self, sample: Any) -> None:
        pose = self._accept(sample, self.odometry, self.config.odom_frame_id)
        if pose is None:
            return
        measured = measured_at(pose.stamp_s, self._wall(), self._monotonic())
        with self._lock:
            steps = self._track.clock_steps
            rejected = self._track.add_odometry(
                pose.stamp_s, (pose.x, pose.y, pose.theta), self._wall()
            )
            if self._track.clock_steps != steps:
                _log.warning("ros2 drive %s: clock stepped back: re-based", self.node_name)
            if rejected is None:
                self._odometry_measured = measured
                self.poses_received += 1
                self._refresh()
                if math.isfinite(pose.u) and math.isfinite(pose.omega):
                    right, left = wheel_speeds(
                        pose.u, pose.omega, self.profile.wheel_radius, self.profile.half_axle
                    )
                    self._wheels = (float(right), float(left), measured)
        self._count(rejected, self.odometry)

    def _on_localiser(self, sample: Any) -> None:
        assert self.localiser is not None
        pose = self._accept(sample, self.localiser, self.config.localiser_frame_id)
        if pose is None:
            return
        with self._lock:
            rejected = self._track.add_localiser(pose.stamp_s, (pose.x, pose.y, pose.theta))
            if rejected is None:
                self.poses_received += 1
                self._refresh()
        self._count(rejected, self.localiser)

    def _count(self, rejected: Rejected | None, topic: Ros2Topic) -> None:
        if rejected is not None:
            self.decoder.drop(rejected.reason, f"{topic.name}: {rejected.detail}")

    def _refresh(self) -> None:
        """Recompute the world-frame reading (lock held)."""
        latest = self._track.latest()
        if latest is None:
            return
        pose, _ = latest
        x, y, theta = compose(self.config.origin, pose)
        self._reading = (Pose(x=x, y=y, theta=theta), self._odometry_measured)
        self._has_pose.set()

    def wait_for_pose(self, timeout: float) -> None:
        """Block until a usable pose has arrived; ConnectionError after ``timeout`` [s]."""
        if self._has_pose.wait(timeout):
            return
        sources = " and ".join(
            f"{t.ros_type} on {t.subscription}"
            for t in (self.odometry, self.localiser)
            if t is not None
        )
        dropped = dict(self.decoder.dropped) or "none"
        raise ConnectionError(
            f"no usable pose from the robot within {timeout:g} s: expected {sources} "
            f"(dropped so far: {dropped}). Check the robot's router (ros2.connect), "
            "ros2.domain_id, ros2.namespace, the topic names and frames."
        )

    @property
    def cmd_vel_subscribed(self) -> bool:
        """Whether a subscriber on the robot's side matches the ``cmd_vel`` key."""
        return bool(self._publisher.matching_status.matching)

    # -- the Drive interface ----------------------------------------------------------------
    def read_pose(self) -> PoseReading:
        """Latest world-frame pose and the monotonic time its message was stamped."""
        with self._lock:
            reading = self._reading
        if reading is None:
            raise RuntimeError("no pose from the robot yet (see Ros2Drive.wait_for_pose)")
        return reading

    def wheel_speeds(self) -> tuple[float, float, float]:
        """The wheel speeds [rad/s] of the newest odometry's twist and the monotonic time of
        its stamp [s] (NaN before any: the latency estimator ignores it)."""
        with self._lock:
            return self._wheels

    def command_wheels(self, right_rad_s: float, left_rad_s: float) -> None:
        """Send the (u, omega) of these wheel speeds (Eq. 2) as the robot's velocity command."""
        u, omega = body_velocities(
            right_rad_s, left_rad_s, self.profile.wheel_radius, self.profile.half_axle
        )
        self._send(float(u), float(omega))
        self._zeros_left = ZERO_REPEATS

    def stop(self) -> None:
        """Command zero velocity, every call: the agent calls it every tick while it holds
        the robot stopped, so a zero goes out at the control rate."""
        self._zeros_left = ZERO_REPEATS
        self._send(0.0, 0.0)

    def release(self) -> None:
        """The robot stands with nothing to do (idle, arrived): zero velocity
        :data:`ZERO_REPEATS` times after motion, then silence (a teleop may use ``cmd_vel``)."""
        if self._zeros_left > 0:
            self._zeros_left -= 1
            self._send(0.0, 0.0)

    def faults(self) -> list[tuple[str, str]]:
        """``(code, message)`` of the drive's faults that hold the robot: ``pose_jump``."""
        with self._lock:
            jumped = self._track.jumped
        if jumped is None:
            return []
        how = (
            "until the next localiser pose re-aligns it"
            if self.localiser is not None
            else "re-align: set ros2.origin and restart the agent"
        )
        return [("pose_jump", f"{jumped}: holding, {how}")]

    def _send(self, u: float, omega: float) -> None:
        c = self.config
        wall = self._wall()
        payload = self.messages.encode_velocity(
            c.cmd_vel_type, u, omega, stamp_s=wall, frame_id=c.base_frame_id
        )
        attachment = None
        if c.key_mapping == "rmw_zenoh":
            attachment = encode_attachment(Attachment(self._sequence, round(wall * 1e9), self._gid))
            self._sequence += 1
        self._publisher.put(payload, attachment=attachment)
        self.commands_sent += 1
        self.last_command = (u, omega)

    def close(self) -> None:
        """Send a last zero, undeclare the tokens, subscribers and publisher (idempotent);
        close the session if the drive owns it."""
        if self._closed:
            return
        self._closed = True
        if hasattr(self, "_publisher"):
            try:
                self._send(0.0, 0.0)
            except Exception:
                _log.debug("last zero command failed", exc_info=True)
        handles, self._handles = self._handles, []
        for handle in reversed(handles):
            try:
                handle.undeclare()
            except Exception:
                _log.debug("undeclare failed", exc_info=True)
        if self._owns_session:
            self._session.close()


def robot_session_settings(settings: RobotSettings) -> RobotSettings:
    """Settings of the drive's session: the agent's own when ``ros2.connect`` is empty, else a
    plain client of the robot's router (the fleet's TLS and credentials left out)."""
    if not settings.ros2.connect:
        return settings
    return settings.model_copy(update={**_FLEET_ONLY, "connect": list(settings.ros2.connect)})


def make_drive(settings: RobotSettings) -> Ros2Drive:
    """Factory of ``parkfleet agent --drive ros2``: opens the robot-side session, declares the
    drive and waits (``ros2.first_pose_timeout_s``) for the robot's first usable pose."""
    robot = robot_session_settings(settings)
    endpoints = ", ".join(robot.connect) or "the default router"
    try:
        session: Any = zenoh.open(zenoh_config(robot, "client"))
    except zenoh.ZError as exc:
        raise ConnectionError(
            f"cannot reach the robot's Zenoh router ({endpoints}): {exc}. Is rmw_zenohd "
            "(or zenoh-bridge-ros2dds) running there, and ros2.connect right?"
        ) from exc
    try:
        drive = Ros2Drive(
            session,
            settings.ros2,
            settings.profile,
            node_name=settings.ros2.node_name or default_node_name(settings.robot_id),
            owns_session=True,
        )
    except BaseException:
        session.close()
        raise
    try:
        drive.wait_for_pose(settings.ros2.first_pose_timeout_s)
    except BaseException:
        drive.close()
        raise
    if not drive.cmd_vel_subscribed:
        _log.warning(
            "ros2 drive: nothing on the robot subscribes to %s yet: commands go nowhere until "
            "something does (check ros2.cmd_vel_topic, ros2.cmd_vel_type, ros2.distro)",
            drive.cmd_vel.key,
        )
    return drive
