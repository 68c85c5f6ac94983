"""``parkfleet agent --drive ros2`` against a stand-in ROS 2 robot written with zenoh-ros2-sdk.

The stand-in is an independent implementation of rmw_zenoh's wire format (zenoh-ros2-sdk,
message definitions and RIHS01 hashes from rosbags' Jazzy typestore, as a Jazzy robot has
them): a unicycle that integrates the last ``cmd_vel`` it received (exactly, on the arc;
no command timeout, so only the agent's zero command stops it) and publishes ``odom`` at
50 Hz, stamped with its wall clock.

* one router (the robot's router meshed with the fleet's, ``ros2.connect`` empty): the real
  fleet service assigns a parking task, the agent (a real ``parkfleet agent`` process) parks
  the stand-in within tolerance; while the odometry is paused the robot holds (pose stale)
  and stands still; the keys on the wire and the ROS graph the robot sees are asserted;
* two routers (the robot's own router, ``ros2.connect``, and the fleet's): when the fleet
  router dies the agent holds and the drive, still linked to the robot, stops it; when the
  router returns the robot drives on.

Real Zenoh over loopback, real processes; waits poll conditions; every process is stopped
and every session closed in ``finally`` blocks.
"""

from __future__ import annotations

import math
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from support import park, read_line, wait_for, zenoh_fleet_service
from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber, ZenohSession, get_topic_info

from fleet.core.control import pose_error
from fleet.core.params import Gains, Tolerance
from fleet.core.tasks import RobotStatus, TaskRequest, TaskStatus
from fleet.core.wire import Keys, Pose, RobotMode, RobotState, encode
from fleet.io.decoder import Decoder
from fleet.io.processes import parkfleet_command, terminate
from fleet.io.settings import load_settings
from fleet.io.transport import open_session

pytestmark = pytest.mark.integration

JAZZY = get_typestore(Stores.ROS2_JAZZY)
KEYS = Keys()
ROBOT_ID = "tb4-1"
#: Gains that park a TurtleBot-4-sized robot in ~15 s (the defaults take ~50 s).
QUICK = Gains(kx=3.0, ky=10.0, ktheta=4.0)
TOLERANCE = Tolerance(position=0.1, heading=0.1)
ROBOT_TOML = """
drive = "ros2"
connect = ["{fleet}"]
link_timeout_s = {link_timeout}

[profile]  # TurtleBot 4 (Create 3 base): 72 mm wheels, 235 mm track, 0.306 m/s
wheel_radius = 0.036
half_axle = 0.1175
max_wheel_speed = 8.5
radius = 0.18

[ros2]
namespace = "/tb4_1"
cmd_vel_type = "geometry_msgs/msg/TwistStamped"
connect = {robot}
"""


class StandInRobot:
    """A ROS 2 robot on rmw_zenoh, written with zenoh-ros2-sdk (see the module docstring)."""

    def __init__(self, endpoint: str, namespace: str, command_type: str) -> None:
        host, port = endpoint.removeprefix("tcp/").rsplit(":", 1)
        self.command_type = command_type
        self.lock = threading.Lock()
        self.x = self.y = self.theta = 0.0
        self.u = self.omega = 0.0
        self.commands = 0
        self.ticks = 0  # of the robot's 50 Hz loop, publishing or not
        self.odometry_sent = 0
        self.last_stamp = 0.0  # [s, wall clock] of the newest odometry published
        self._t = time.monotonic()
        self.publishing = threading.Event()
        self.publishing.set()
        self._stop = threading.Event()
        common: dict[str, Any] = {"router_ip": host, "router_port": int(port), "domain_id": 0}
        # the two traps of shared/DESIGN.md: pass the definition AND the RIHS01 hash
        self.cmd_vel = ROS2Subscriber(
            f"{namespace}/cmd_vel", command_type, self._on_command, node_name="create3",
            msg_definition=JAZZY.generate_msgdef(command_type, ros_version=2)[0],
            type_hash=JAZZY.hash_rihs01(command_type), namespace=namespace, **common,
        )  # fmt: skip
        odometry = "nav_msgs/msg/Odometry"
        self.odom = ROS2Publisher(
            f"{namespace}/odom", odometry, node_name="create3",
            msg_definition=JAZZY.generate_msgdef(odometry, ros_version=2)[0],
            type_hash=JAZZY.hash_rihs01(odometry), namespace=namespace, **common,
        )  # fmt: skip
        self._types = self.odom.session_mgr.store.types
        self._thread = threading.Thread(target=self._odometry_loop, name="stand-in odom")
        self._thread.start()

    def _advance(self) -> None:
        """Move on the arc of the held (u, omega) up to now (lock held)."""
        now = time.monotonic()
        dt, self._t = now - self._t, now
        u, w, th = self.u, self.omega, self.theta
        if abs(w) < 1e-9:
            self.x += u * math.cos(th) * dt
            self.y += u * math.sin(th) * dt
        else:
            self.x += u / w * (math.sin(th + w * dt) - math.sin(th))
            self.y -= u / w * (math.cos(th + w * dt) - math.cos(th))
            self.theta = th + w * dt

    def _on_command(self, message: Any) -> None:
        twist = message.twist if self.command_type.endswith("Stamped") else message
        with self.lock:
            self._advance()
            self.u, self.omega = float(twist.linear.x), float(twist.angular.z)
            self.commands += 1

    def _odometry_loop(self) -> None:
        t = self._types
        while not self._stop.wait(0.02):  # the robot's own 50 Hz loop
            self.ticks += 1
            if not self.publishing.is_set():
                continue
            with self.lock:
                self._advance()
                x, y, theta, u, omega = self.x, self.y, self.theta, self.u, self.omega
            stamp = time.time()
            vector = t["geometry_msgs/msg/Vector3"]
            self.odom.publish(
                header=t["std_msgs/msg/Header"](
                    stamp=t["builtin_interfaces/msg/Time"](
                        sec=int(stamp), nanosec=int((stamp % 1) * 1e9)
                    ),
                    frame_id="odom",
                ),
                child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](
                    pose=t["geometry_msgs/msg/Pose"](
                        position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                        orientation=t["geometry_msgs/msg/Quaternion"](
                            x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2)
                        ),
                    ),
                    covariance=np.zeros(36),
                ),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](
                    twist=t["geometry_msgs/msg/Twist"](
                        linear=vector(x=u, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=omega)
                    ),
                    covariance=np.zeros(36),
                ),
            )
            self.odometry_sent += 1
            self.last_stamp = stamp

    def pose(self) -> tuple[float, float, float]:
        with self.lock:
            self._advance()
            return (self.x, self.y, self.theta)

    def velocity(self) -> tuple[float, float]:
        with self.lock:
            return (self.u, self.omega)

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.cmd_vel.close()
        self.odom.close()
        ZenohSession.get_instance().close()  # the SDK's one session per process


@contextmanager
def stand_in(endpoint: str, command_type: str) -> Iterator[StandInRobot]:
    robot = StandInRobot(endpoint, "/tb4_1", command_type)
    try:
        yield robot
    finally:
        robot.close()


@contextmanager
def agent(config: Path, log: Path) -> Iterator[subprocess.Popen[bytes]]:
    """``parkfleet agent --id tb4-1 --drive ros2 --config robot.toml``, up and running."""
    command = parkfleet_command(
        "agent", "--id", ROBOT_ID, "--drive", "ros2", "--config", str(config)
    )
    with log.open("wb") as err:
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=err)
        try:
            assert read_line(proc, 60).startswith(f"agent {ROBOT_ID} running"), log.read_text()
            yield proc
        finally:
            code = terminate(proc)
            assert proc.stdout is not None
            proc.stdout.close()
    # SIGTERM: a clean exit (an unclosed drive session would hang it until SIGKILL)
    assert code == 0, log.read_text()


class WireTap:
    """Every key (and its payload and attachment sizes) seen on ``0/**`` of a router."""

    def __init__(self, session: Any) -> None:
        self.lock = threading.Lock()
        self.seen: dict[str, tuple[int, int]] = {}
        self.sub = session.declare_subscriber("0/**", self._on)

    def _on(self, sample: Any) -> None:
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
        with self.lock:
            self.seen[str(sample.key_expr)] = (len(sample.payload.to_bytes()), len(attachment))

    def keys(self) -> dict[str, tuple[int, int]]:
        with self.lock:
            return dict(self.seen)


def cmd_vel_publishers() -> set[tuple[str, str, str]]:
    """(node, namespace, type) of the publishers the robot's ROS graph shows on its cmd_vel."""
    info = get_topic_info("/tb4_1/cmd_vel", verbose=True, timeout=1.0)
    if info is None:
        return set()
    return {(p.node_name, p.node_namespace, p.topic_type) for p in info.publishers}


def test_agent_parks_the_ros2_robot_and_holds_while_its_odometry_stops(
    router_endpoint: str, tmp_path: Path
) -> None:
    config = tmp_path / "robot.toml"
    config.write_text(ROBOT_TOML.format(fleet=router_endpoint, link_timeout=3.0, robot="[]"))
    settings = load_settings(connect=[router_endpoint], task_timeout_s=120.0)
    twist_stamped = "geometry_msgs/msg/TwistStamped"
    goal = Pose(x=1.0, y=0.5, theta=0.8)
    with (
        open_session(settings, "client") as wire,
        stand_in(router_endpoint, twist_stamped) as robot,
        zenoh_fleet_service(settings, tmp_path / "fleet.db") as service,
        agent(config, tmp_path / "agent.log"),
    ):
        tap = WireTap(wire)
        try:
            wait_for(lambda: ROBOT_ID in {r.robot_id for r in service.robots()}, 30, "the robot")
            ours = {("parkfleet_tb4_1", "/tb4_1", twist_stamped)}  # `ros2 topic info -v`
            wait_for(lambda: cmd_vel_publishers() == ours, 30, "the agent in the ROS graph")
            tokens = sorted(
                str(reply.ok.key_expr)
                for reply in wire.liveliness().get("@ros2_lv/0/**")
                if reply.ok is not None and "/parkfleet_tb4_1" in str(reply.ok.key_expr)
            )
            request = TaskRequest(goal=goal, robot_id=ROBOT_ID, direction="cw", gains=QUICK)
            task = service.submit(request)
            wait_for(lambda: robot.pose()[0] > 0.15, 60, "the robot under way")
            robot.publishing.clear()  # the odometry stops...
            wait_for(lambda: service.robot(ROBOT_ID).status is RobotStatus.HOLDING, 30, "hold")
            held_after = time.time() - robot.last_stamp  # since the last pose's stamp
            wait_for(lambda: robot.velocity() == (0.0, 0.0), 10, "a zero command")
            still, ticks = robot.pose(), robot.ticks
            wait_for(lambda: robot.ticks > ticks + 25, 10, "half a second of the robot's time")
            assert math.dist(robot.pose()[:2], still[:2]) < 1e-9  # it stands still
            assert service.task(task.id).status is TaskStatus.DRIVING  # its task kept
            robot.publishing.set()  # ...and comes back: the robot drives on
            wait_for(lambda: service.task(task.id).status.final, 90, "the task to finish")
            final = service.task(task.id)
            wait_for(lambda: robot.velocity() == (0.0, 0.0), 10, "stopped at the goal")
            parked = robot.pose()
            keys = tap.keys()
        finally:
            tap.sub.undeclare()
    x_e, y_e, theta_e = pose_error(parked, goal.as_tuple(), False)
    print(f"ros2 stand-in parked at {parked} for goal {goal.as_tuple()}; held {held_after:.2f} s")
    print("keys on the wire:", *(f"  {k}: {v[0]} B payload, {v[1]} B attachment"
                                 for k, v in sorted(keys.items())), *tokens, sep="\n")  # fmt: skip
    assert final.status is TaskStatus.SUCCEEDED, final
    heading_error = abs(math.remainder(float(theta_e), 2 * math.pi))
    assert math.hypot(x_e, y_e) < TOLERANCE.position and heading_error < TOLERANCE.heading
    assert held_after >= settings.pose_stale_s  # not before the pose was stale
    cmd_vel = "0/tb4_1/cmd_vel/geometry_msgs::msg::dds_::TwistStamped_/" + (
        JAZZY.hash_rihs01(twist_stamped)
    )
    odom = "0/tb4_1/odom/nav_msgs::msg::dds_::Odometry_/" + JAZZY.hash_rihs01(
        "nav_msgs/msg/Odometry"
    )
    # payload bytes: TwistStamped 4 + 24 (stamp, "base_link") + 48; Odometry 724; attachments 33
    assert keys == {cmd_vel: (76, 33), odom: (724, 33)}
    node = "%tb4_1/parkfleet_tb4_1"
    assert [t.split("/", 3)[3] for t in tokens] == [  # @ros2_lv/0/<zenoh id>/...
        f"0/0/NN/%/{node}",
        f"0/1/MP/%/{node}/{cmd_vel.replace('0/tb4_1/cmd_vel', '%tb4_1%cmd_vel')}/::,1:,:,:,,",
        f"0/2/MS/%/{node}/{odom.replace('0/tb4_1/odom', '%tb4_1%odom')}/2::,5:,:,:,,",
    ]


def test_cut_from_the_fleet_router_the_agent_stops_the_ros2_robot_and_resumes(
    router_endpoint: str, tmp_path: Path
) -> None:
    """The robot's router (``router_endpoint``) stays; the fleet's router dies and returns."""
    decoder = Decoder("test")
    states: list[RobotState] = []

    def on_state(sample: Any) -> None:
        state = decoder.decode(RobotState, sample.payload.to_bytes())
        if state is not None:
            states.append(state)

    fleet_router = subprocess.Popen(
        parkfleet_command("router", "--listen", "tcp/127.0.0.1:0"), stdout=subprocess.PIPE
    )
    again: subprocess.Popen[bytes] | None = None
    try:
        fleet = read_line(fleet_router, 30).split()[-1]
        config = tmp_path / "robot.toml"
        robot_router = f'["{router_endpoint}"]'
        config.write_text(ROBOT_TOML.format(fleet=fleet, link_timeout=1.0, robot=robot_router))
        settings = load_settings(connect=[fleet])
        with (
            stand_in(router_endpoint, "geometry_msgs/msg/TwistStamped") as robot,
            open_session(settings, "client") as fleet_session,
            agent(config, tmp_path / "agent.log"),
        ):
            sub = fleet_session.declare_subscriber(KEYS.state(ROBOT_ID), on_state)
            try:
                message = park(ROBOT_ID, "far", (4.0, 1.0, 0.0), gains=QUICK)

                def acked() -> bool:
                    fleet_session.put(KEYS.assignment(ROBOT_ID), encode(message))
                    return any(s.task_id == "far" and s.mode is RobotMode.DRIVING for s in states)

                wait_for(acked, 30, "the robot driving its task")
                wait_for(lambda: robot.pose()[0] > 0.1, 30, "the robot under way")
                assert robot.velocity()[0] > 0.0
                fleet_router.kill()  # the fleet's router dies; the robot's router stays
                cut_at = time.monotonic()
                fleet_router.wait(10)
                wait_for(lambda: robot.velocity() == (0.0, 0.0), 10, "the robot stopped")
                stopped_after = time.monotonic() - cut_at
                still, odometry = robot.pose(), robot.odometry_sent
                wait_for(lambda: robot.odometry_sent > odometry + 25, 10, "half a second on")
                assert math.dist(robot.pose()[:2], still[:2]) < 1e-9  # it stays stopped
                port = fleet.rsplit(":", 1)[1]
                again = subprocess.Popen(
                    parkfleet_command("router", "--listen", f"tcp/127.0.0.1:{port}"),
                    stdout=subprocess.PIPE,
                )
                assert read_line(again, 30).startswith("router listening")
                wait_for(lambda: robot.velocity()[0] > 0.0, 30, "the robot driving again")
                wait_for(lambda: math.dist(robot.pose()[:2], still[:2]) > 0.05, 30, "moving")
            finally:
                sub.undeclare()
    finally:
        for proc in (fleet_router, again):
            if proc is not None:
                terminate(proc)
                assert proc.stdout is not None
                proc.stdout.close()
    print(
        f"fleet link cut: the ROS 2 robot got its zero command {stopped_after * 1000:.0f} ms later"
    )
    err = (tmp_path / "agent.log").read_text()
    assert "link to the fleet network lost" in err and "Traceback" not in err


def test_agent_without_odometry_exits_with_the_reason(router_endpoint: str, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text(
        ROBOT_TOML.format(fleet=router_endpoint, link_timeout=3.0, robot="[]")
        + "first_pose_timeout_s = 0.5\n"
    )
    command = parkfleet_command(
        "agent", "--id", ROBOT_ID, "--drive", "ros2", "--config", str(config)
    )
    done = subprocess.run(command, capture_output=True, timeout=60, check=False)
    assert done.returncode == 2
    assert b"no usable pose from the robot within 0.5 s" in done.stderr
    assert b"nav_msgs/msg/Odometry on 0/tb4_1/odom/*/*" in done.stderr
