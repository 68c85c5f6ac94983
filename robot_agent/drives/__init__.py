"""Ready-made drives for ``parkfleet agent --drive NAME`` (``fleet.cli.agent.DRIVES``).

``ros2`` -- a ROS 2 robot over Zenoh, no ROS installation needed on the fleet side:

- :mod:`~robot_agent.drives.ros2` -- the Drive (``Ros2Drive``, ``make_drive``): the I/O
  edge -- its Zenoh session, the ``cmd_vel`` publisher, the pose subscriptions, the
  ROS-graph liveliness tokens, drop counters;
- :mod:`~robot_agent.drives.ros2_names` -- pure: ROS names as rmw_zenoh or
  zenoh-bridge-ros2dds key expressions, liveliness token names, QoS strings;
- :mod:`~robot_agent.drives.ros2_attachment` -- rmw_zenoh's per-message attachment
  (sequence number, source timestamp, GID);
- :mod:`~robot_agent.drives.ros2_messages` -- pure: CDR of Twist / TwistStamped /
  Odometry / PoseWithCovarianceStamped through rosbags, type hashes;
- :mod:`~robot_agent.drives.ros2_pose` -- pure: frames (world = origin ∘ pose), stamp
  checks, ROS stamps on the monotonic clock, a localiser carried forward by odometry.

Settings: ``fleet.io.settings.Ros2Settings`` (TOML ``[ros2]``); docs/robots.md, "Driving a
ROS 2 robot".
"""

__all__: list[str] = []
