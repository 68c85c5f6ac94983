"""The agent that runs on a robot: control loop at 50 Hz, state over Zenoh, a Drive for the
hardware.

- :mod:`~robot_agent.drive`: the :class:`Drive` interface a robot implements (world-frame
  pose in, wheel speeds out) -- the one file a robot integrator reads.
- :mod:`~robot_agent.logic`: the pure per-tick decision (task protocol, modes, control).
- :mod:`~robot_agent.world` / :mod:`~robot_agent.world_feed`: the peers and obstacles a
  robot knows, and their Zenoh feed.
- :mod:`~robot_agent.link`: whether the robot is still in touch with the fleet network.
- :mod:`~robot_agent.clock`: real and stepped clocks, the periodic scheduler.
- :mod:`~robot_agent.agent`: :class:`RobotAgent`, which ties them to a Zenoh session.

Run one with ``parkfleet agent --id ID --drive module:factory``.
"""

from robot_agent.agent import RobotAgent
from robot_agent.drive import Drive, PoseReading

__all__ = ["Drive", "PoseReading", "RobotAgent"]
