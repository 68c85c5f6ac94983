"""From ROS pose messages to the fleet's world-frame pose and its measurement time (pure).

Frames (REP-105): the robot's odometry is the pose of its base in the ``odom`` frame,
continuous but drifting; a localiser (AMCL, a motion-capture or UWB system …) gives the
pose in the ``map`` frame, often only now and then (AMCL publishes after the robot has
moved). The fleet's world frame is related to the message frame by
``Ros2Settings.origin`` (the frame's pose in the world): world = origin ∘ pose.

* :func:`check_pose` -- a measurement the agent must not use: wrong frame, no stamp, or
  a stamp from the future (beyond a clock-skew allowance). The drive drops, counts and
  logs it; the robot holds once its last good pose is stale.
* :func:`measured_at` -- a header stamp (ROS time = the wall clock of the publisher) as
  a time on this computer's monotonic clock, the clock the agent's staleness check uses.
* :class:`PoseTrack` -- the latest pose in the localiser's (or odometry's) frame: with a
  localiser, its latest pose corrected forward by the odometry since its stamp, exactly
  as ROS's ``map -> odom`` transform is (the correction is recomputed on every localiser
  pose, from the odometry interpolated at that pose's stamp).
* :func:`odometry_jump` -- an odometry step that motion at the robot's top speed cannot
  explain, or odometry back at ~its origin (a base that rebooted or reset its odometry):
  the track keeps the new odometry, forgets the history across the jump and reports it
  (:attr:`PoseTrack.jumped`, the agent's ``pose_jump`` fault) until re-aligned -- by the
  next localiser pose stamped after the jump, or, with odometry only, never in this run
  (docs/robots.md "Where the two links go": set ``ros2.origin`` and restart the agent).
* Clock steps -- an odometry stamp more than ``clock_step_s`` behind the newest one but
  close to this computer's clock (a clock without RTC set by NTP, a step back) re-bases
  the track (history forgotten, counted in :attr:`PoseTrack.clock_steps`) instead of
  dropping every later pose as out of order.

Poses are ``(x [m], y [m], theta [rad])`` tuples; angles counter-clockwise.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass

from fleet.core.types import Posture
from fleet.core.wire import Rejected
from robot_agent.drives.ros2_messages import StampedPose

#: Odometry poses remembered for matching a localiser's stamp (~10 s at 50 Hz).
ODOMETRY_HISTORY = 512
#: How far [s] past the newest odometry a localiser stamp may be and still use it.
MAX_LOCALISER_LEAD_S = 0.2
#: Odometry within this distance [m] and angle [rad] of its origin counts as "reset".
RESET_RADIUS_M = 0.01
RESET_ANGLE_RAD = 0.01


@dataclass(frozen=True)
class JumpLimits:
    """What consecutive odometry poses may differ by: the robot's top speed [m/s] and turn
    rate [rad/s] times the time between their stamps, plus a slack [m] / [rad] for noise,
    wheel slip and a teleop a little faster than the fleet's profile."""

    top_speed: float
    top_turn: float
    slack_m: float
    slack_rad: float


def odometry_jump(previous: Posture, pose: Posture, dt: float, limits: JumpLimits) -> str | None:
    """Why the step ``previous`` -> ``pose`` over ``dt`` [s] is a jump, or None.

    A jump: farther than ``top_speed * dt + slack_m``, or turned more than
    ``top_turn * dt + slack_rad``, or back within :data:`RESET_RADIUS_M` /
    :data:`RESET_ANGLE_RAD` of the odometry origin from farther than ``slack_m`` away
    (the reset signature, whatever ``dt``: a base that rebooted after a long silence).
    """
    dt = max(dt, 0.0)
    moved = math.hypot(pose[0] - previous[0], pose[1] - previous[1])
    turned = abs(wrap_angle(pose[2] - previous[2]))
    if moved > limits.top_speed * dt + limits.slack_m:
        return f"odometry moved {moved:.3f} m in {dt:.3f} s"
    if turned > limits.top_turn * dt + limits.slack_rad:
        return f"odometry turned {turned:.3f} rad in {dt:.3f} s"
    at_origin = math.hypot(pose[0], pose[1]) <= RESET_RADIUS_M and (
        abs(wrap_angle(pose[2])) <= RESET_ANGLE_RAD
    )
    if at_origin and math.hypot(previous[0], previous[1]) > limits.slack_m:
        return f"odometry reset to its origin from {moved:.3f} m away"
    return None


def wrap_angle(theta: float) -> float:
    """The angle in [-pi, pi)."""
    return (theta + math.pi) % (2.0 * math.pi) - math.pi


def compose(a: Posture, b: Posture) -> Posture:
    """a ∘ b: pose ``b`` (given in frame ``a``) expressed in the frame ``a`` is given in."""
    ax, ay, at = a
    bx, by, bt = b
    c, s = math.cos(at), math.sin(at)
    return (ax + c * bx - s * by, ay + s * bx + c * by, wrap_angle(at + bt))


def invert(a: Posture) -> Posture:
    """The inverse transform: ``compose(invert(a), a)`` is the identity."""
    ax, ay, at = a
    c, s = math.cos(at), math.sin(at)
    return (-c * ax - s * ay, s * ax - c * ay, wrap_angle(-at))


def interpolate(a: Posture, b: Posture, fraction: float) -> Posture:
    """The pose ``fraction`` of the way from ``a`` to ``b`` (heading the short way round)."""
    turn = wrap_angle(b[2] - a[2])
    return (
        a[0] + (b[0] - a[0]) * fraction,
        a[1] + (b[1] - a[1]) * fraction,
        wrap_angle(a[2] + turn * fraction),
    )


def check_pose(
    pose: StampedPose, expected_frame: str, wall_now: float, max_future_s: float
) -> Rejected | None:
    """Why ``pose`` must not be used (None if it may): ``wrong_frame``, ``unstamped``
    (stamp zero or negative) or ``future_stamp`` (more than ``max_future_s`` after
    ``wall_now``, this computer's clock [s since the Unix epoch])."""
    if pose.frame_id.lstrip("/") != expected_frame.lstrip("/"):
        return Rejected("wrong_frame", f"frame {pose.frame_id!r}, expected {expected_frame!r}")
    if not pose.stamp_s > 0.0:
        return Rejected("unstamped", f"stamp {pose.stamp_s}")
    ahead = pose.stamp_s - wall_now
    if ahead > max_future_s:
        return Rejected("future_stamp", f"stamped {ahead:.3f} s ahead of this clock")
    return None


def measured_at(stamp_s: float, wall_now: float, monotonic_now: float) -> float:
    """The monotonic time [s] of a measurement stamped ``stamp_s`` (wall clock), read at
    ``wall_now`` / ``monotonic_now``; a stamp slightly ahead (clock skew) counts as now."""
    return monotonic_now - max(0.0, wall_now - stamp_s)


class PoseTrack:
    """The robot's latest pose in the pose frame (``odom`` or the localiser's ``map``).

    Without a localiser the latest odometry is the pose. With one, the pose is
    ``correction ∘ latest odometry`` where ``correction = localiser pose ∘ inverse(odometry
    at the localiser's stamp)``; there is no pose until the first localiser pose.
    Not thread-safe: the drive holds a lock around it.

    ``jump`` (None: no jump detection) bounds consecutive odometry poses
    (:func:`odometry_jump`); ``clock_step_s`` [s] is how far a stamp may go back before it
    is taken for a clock step rather than a late message (module docstring).
    """

    def __init__(
        self,
        *,
        localiser: bool,
        history: int = ODOMETRY_HISTORY,
        jump: JumpLimits | None = None,
        clock_step_s: float = 1.0,
    ) -> None:
        self.localiser = localiser
        self.jump = jump
        self.clock_step_s = clock_step_s
        self._stamps: deque[float] = deque(maxlen=history)
        self._poses: deque[Posture] = deque(maxlen=history)
        self._correction: Posture | None = None if localiser else (0.0, 0.0, 0.0)
        self.jumped: str | None = None  # why the odometry jumped, until re-aligned
        self.clock_steps = 0  # re-bases after a clock stepped back
        self._pending: tuple[float, Posture] | None = None  # localiser pose ahead of odometry

    def add_odometry(
        self, stamp_s: float, pose: Posture, wall_now: float | None = None
    ) -> Rejected | None:
        """Record an odometry pose; ``out_of_order`` if older than the newest one.

        A stamp more than ``clock_step_s`` behind the newest but within ``clock_step_s`` of
        ``wall_now`` (this computer's clock, stepped back with the robot's) re-bases the
        track: the history is forgotten and the pose kept (a clock step, not a late message).
        """
        dt = 0.0
        if self._stamps:
            dt = stamp_s - self._stamps[-1]
            if dt < 0.0:
                stepped = -dt > self.clock_step_s and (
                    wall_now is not None and abs(wall_now - stamp_s) <= self.clock_step_s
                )
                if not stepped:
                    return Rejected(
                        "out_of_order", f"odometry stamp {stamp_s} < {self._stamps[-1]}"
                    )
                self.clock_steps += 1
                previous = self._poses[-1]
                self._stamps.clear()
                self._poses.clear()
                self._stamps.append(stamp_s)
                self._poses.append(previous)  # the jump check below sees dt = 0
                dt = 0.0
        if self.jump is not None and self._poses:
            why = odometry_jump(self._poses[-1], pose, dt, self.jump)
            if why is not None:
                self.jumped = why
                self._stamps.clear()  # interpolating across a jump means nothing
                self._poses.clear()
        if self._stamps and self._stamps[-1] == stamp_s:
            self._stamps.pop()
            self._poses.pop()
        self._stamps.append(stamp_s)
        self._poses.append(pose)
        pending, self._pending = self._pending, None
        if pending is not None:  # a localiser pose that came before its odometry (latched)
            self.add_localiser(*pending)
        return None

    def odometry_at(self, stamp_s: float) -> Posture | None:
        """The odometry pose at ``stamp_s``, interpolated; None outside the history."""
        stamps = list(self._stamps)
        if not stamps or stamp_s < stamps[0]:
            return None
        if stamp_s >= stamps[-1]:
            return self._poses[-1] if stamp_s - stamps[-1] <= MAX_LOCALISER_LEAD_S else None
        i = bisect.bisect_right(stamps, stamp_s)  # stamps[i - 1] <= stamp_s < stamps[i]
        t0, t1 = stamps[i - 1], stamps[i]
        fraction = (stamp_s - t0) / (t1 - t0) if t1 > t0 else 0.0
        return interpolate(self._poses[i - 1], self._poses[i], fraction)

    def add_localiser(self, stamp_s: float, pose: Posture) -> Rejected | None:
        """Re-anchor on a localiser pose; ``no_odometry`` if no odometry covers its stamp."""
        odometry = self.odometry_at(stamp_s)
        if odometry is None:
            if not self._stamps or stamp_s > self._stamps[-1]:
                self._pending = (stamp_s, pose)  # retried when the odometry catches up
            return Rejected("no_odometry", f"no odometry around localiser stamp {stamp_s}")
        self._correction = compose(pose, invert(odometry))
        self.jumped = None  # history starts after any jump: this pose re-aligns the track
        return None

    def latest(self) -> tuple[Posture, float] | None:
        """(pose in the pose frame, its stamp [s, ROS time]) or None while there is none."""
        if self._correction is None or not self._stamps:
            return None
        return compose(self._correction, self._poses[-1]), self._stamps[-1]
