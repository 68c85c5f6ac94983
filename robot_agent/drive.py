"""The ``Drive`` interface: the only code a user writes to put a real robot in the fleet.

A ``Drive`` connects :class:`robot_agent.agent.RobotAgent` to one robot's hardware:

* :meth:`Drive.read_pose` -- where the robot is, in the **world frame** (x, y [m],
  theta [rad], counter-clockwise from the world x axis), and **when** that pose was
  measured, in seconds on the agent's clock (``time.monotonic()`` for a real robot, or
  ``clock.now()`` of the :class:`~robot_agent.clock.Clock` the agent was given). The agent
  stops the robot (mode ``holding``) when that stamp is older than
  ``Settings.pose_stale_s``, so stamp the *measurement*, not the call: a localisation
  stack that stopped updating must look stale.
* :meth:`Drive.command_wheels` -- set the right and left wheel angular speeds [rad/s]
  (positive = forward). The agent already respects ``RobotProfile.max_wheel_speed``
  (both wheels scaled together so the path curvature is kept, Eq. 2); the drive holds the
  command until the next one (zero-order hold). The agent commands at its control rate.
* :meth:`Drive.stop` -- stop both wheels now. Called on shutdown, when a tick fails and
  on every tick the robot is held stopped for a reason (e-stop, pause, holding, link
  lost, pose stale or jumped, waiting); it must be safe to call at any time and repeatedly.
* Optional ``release()`` -- called instead of ``stop()`` on ticks the robot stands with
  nothing to do (idle, arrived): a drive may stop commanding (the ros2 drive falls silent
  so an operator can teleop). Optional ``faults()`` -- ``(code, message)`` pairs of the
  drive's own faults; while any is reported the agent holds and lists it in
  ``RobotState.errors`` (the ros2 drive's ``pose_jump``). Optional ``wheel_speeds()`` --
  the right and left wheel speeds [rad/s] the wheels were *measured* turning at (encoders,
  or odometry's twist by Eq. 2), and when, on the agent's clock: ``(right, left, at)``
  (:data:`WheelReading`). The agent reads it every tick and measures its command-to-wheel
  latency from it (:mod:`robot_agent.latency`): without it the latency is taken to be
  anywhere in [0, ``SafetyConfig.max_latency_s``], which widens the robot's own spread.
  Report what turns, not what was commanded: a drive that echoes its last command
  measures no latency (the simulated drives report the wheels actually turning).

Calls come from one thread (the agent's control loop), never concurrently. Methods should
return quickly (well under one control period); raise an exception on a hardware fault,
the agent counts it, logs it and stops the robot.

Example, wrapping a motor controller and a localisation source::

    import time
    from fleet.core.wire import Pose

    class MyDrive:
        def __init__(self, settings):
            self.motors = MotorBoard("/dev/ttyACM0")
            self.localiser = Localiser()

        def read_pose(self):
            x, y, theta, t_measured = self.localiser.latest()  # t on time.monotonic()
            return Pose(x=x, y=y, theta=theta), t_measured

        def command_wheels(self, right_rad_s, left_rad_s):
            self.motors.set_speeds(right_rad_s, left_rad_s)

        def stop(self):
            self.motors.set_speeds(0.0, 0.0)

    def make_drive(settings):  # parkfleet agent --id r1 --drive mypackage.mydrive:make_drive
        return MyDrive(settings)
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from fleet.core.wire import Pose

PoseReading = tuple[Pose, float]
"""A world-frame pose and the time [s, agent clock] it was measured."""

WheelReading = tuple[float, float, float]
"""Measured right and left wheel speeds [rad/s] and the time [s, agent clock] they were
measured (the optional ``wheel_speeds()``)."""


@runtime_checkable
class Drive(Protocol):
    """Hardware boundary of one differential-drive robot (see the module docstring)."""

    def read_pose(self) -> PoseReading:
        """Latest world-frame pose and its measurement time [s] on the agent's clock."""
        ...

    def command_wheels(self, right_rad_s: float, left_rad_s: float) -> None:
        """Hold right/left wheel angular speeds [rad/s] until the next command."""
        ...

    def stop(self) -> None:
        """Stop both wheels immediately; idempotent."""
        ...
