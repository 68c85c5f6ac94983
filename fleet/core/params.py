"""Validated parameter models shared by the simulator, the agents and the service."""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]


class Gains(BaseModel):
    """Controller gains (kx [1/s], ky, ktheta) of laws (17)/(20); all strictly positive."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kx: PositiveFloat
    ky: PositiveFloat
    ktheta: PositiveFloat

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.kx, self.ky, self.ktheta)


class Tolerance(BaseModel):
    """Arrival tolerance: position [m] and heading [rad] (strict inequalities)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    position: PositiveFloat = 0.05
    heading: PositiveFloat = 0.02


class RobotProfile(BaseModel):
    """Physical profile of a differential-drive robot (Eq. 2 and Table 10 of the paper).

    ``max_wheel_speed`` [rad/s] may be ``inf`` for an unlimited (paper) robot.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    wheel_radius: PositiveFloat = 0.05
    half_axle: PositiveFloat = 0.135
    max_wheel_speed: Annotated[float, Field(gt=0.0)] = 20.0
    radius: PositiveFloat = 0.2

    @property
    def max_speed(self) -> float:
        """Top forward speed [m/s] with both wheels at the limit."""
        return self.wheel_radius * self.max_wheel_speed


class Avoidance(BaseModel):
    """Obstacle repulsion of Eq. (27): K_avoid [m^2/s], influence radii [m], x_OA guard [m].

    ``smoothing_m`` [m]: the width of the bands over which the term is made continuous
    (:func:`fleet.core.step.repulsion_term`): faded in over the outer ``smoothing_m`` of each
    influence radius, linear through 0 for |x_OA| below it. The paper's term jumps at both
    (from 0 to -K_avoid / radius at the edge; from -K_avoid / min_x_oa to +K_avoid / min_x_oa
    abeam), so a robot's pose noise there flips its speed tick by tick (the stop-and-turn
    of docs/benchmarks.md). 0: the paper's term exactly.

    The default, 0.6 m, keeps the term's slopes low enough for command latency: a robot
    held by the term (speed u = law + term, decided tau [s] before the wheels turn at it)
    is, about its standstill, the loop ds/dt = -a s(t - tau) in its advance s [m], with a
    the term's slope [1/s]: it oscillates once a tau > pi/2.
    The slope is K_avoid / w^2 in the abeam band (4 / 0.6^2 = 11 /s; 64 /s at 0.25 m)
    and about K_avoid / (radius w) at the fade's edge (a peer: 6.7 /s; 16 /s at 0.25 m),
    against pi / (2 x 0.15 s) = 10 /s at ``SafetyConfig.max_latency_s``'s default: the
    band at the edge of it for the slowest latency, the fade below (docs/benchmarks.md,
    "Eq. (27)'s bands widened for latency").
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    k_avoid: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 4.0
    peer_radius: PositiveFloat = 1.0
    min_x_oa: PositiveFloat = 0.05
    smoothing_m: Annotated[float, Field(ge=0.0, le=5.0, allow_inf_nan=False)] = 0.6


class SafetyConfig(BaseModel):
    """The safety filter every robot runs each tick (docs/safety.md; ``fleet.core.step``).

    ``contact_margin_m`` [m]: no body is to come closer than this to another robot's or an
    obstacle's body. ``projection_m`` [m]: the point ahead of the axle (at most the half
    axle); ``barrier_rate`` [1/s]: how fast a clearance may be used up.

    With ``compensate_latency`` (off by default: docs/safety.md, "Latency compensation")
    the paper's law and Eq. (27) decide on the robot's pose predicted for the instant its
    command acts (its commands in flight carried forward at its latency window's middle:
    :func:`robot_agent.prediction.nominal_pose`), so that command latency does not
    turn Eq. (27)'s stiff repulsion into an oscillation (stop and reverse); the safety
    filter keeps the measured pose and the spreads below, so the guarantee is the same
    either way.

    With ``prediction`` (off by default: docs/safety.md, "Latency where it lives") the robot
    decides on its pose predicted for the instant its command acts
    (:mod:`robot_agent.prediction`), sees each peer around the pose that peer predicted for
    itself, and caps its speed-ups; without it, on its measured pose with :meth:`own_spread`
    and its peers with :meth:`peer_spread`. The spreads assume:

    * command-to-wheel latency within the window the robot measures
      (:mod:`robot_agent.latency`), or within [0, ``max_latency_s``] [s] before it has
      measured one (a measured latency above ``max_latency_s`` is reported, fault
      ``latency_exceeded``, and used);
    * a peer's state reaches the robot within ``link_delay_s`` [s] of being sent; its send
      time is taken from its arrival less that bound, or, with ``clock_sync_s`` [s] set
      (the robots' wall clocks agree within it: chrony, PTP), from its stamp;
    * position errors of a measured pose at most ``pose_error_m`` [m], heading errors at
      most ``heading_error_rad`` [rad];
    * each wheel turning at its commanded speed within a relative ``actuation_error``;
    * the speed of the point the filter watches (``projection_m`` ahead of the axle; with
      the actuation error) rising by at most ``max_accel_m_s2`` [m/s^2] (every agent caps
      its commands' speed-ups so; braking and turning are not limited);
    * every robot running the agent; a robot silent to its peers for ``peer_stale_s`` [s]
      has stopped (its agent holds when it has heard nothing for its link timeout, which
      settings keep at most ``peer_stale_s``; its drive stops when its agent dies): a peer's
      spread grows with its silence for ``peer_stale_s``, after which it is a standing
      obstacle at its last pose.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    enabled: bool = True
    contact_margin_m: Annotated[float, Field(ge=0.0, le=2.0, allow_inf_nan=False)] = 0.05
    projection_m: Annotated[float, Field(gt=0.0, le=0.5, allow_inf_nan=False)] = 0.03
    barrier_rate: Annotated[float, Field(gt=0.0, le=100.0, allow_inf_nan=False)] = 5.0
    max_latency_s: Annotated[float, Field(ge=0.0, le=2.0, allow_inf_nan=False)] = 0.15
    link_delay_s: Annotated[float, Field(ge=0.0, le=5.0, allow_inf_nan=False)] = 0.2
    pose_error_m: Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)] = 0.02
    max_accel_m_s2: Annotated[float, Field(gt=0.0, le=100.0, allow_inf_nan=False)] = 1.0
    peer_stale_s: Annotated[float, Field(gt=0.0, le=60.0, allow_inf_nan=False)] = 3.0
    heading_error_rad: Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)] = 0.02
    actuation_error: Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)] = 0.05
    clock_sync_s: Annotated[float, Field(ge=0.0, le=5.0, allow_inf_nan=False)] | None = None
    prediction: bool = False
    compensate_latency: bool = False

    def filter_terms(self, spread: float) -> tuple[float, float, float, float]:
        """The compiled step's filter parameters (``fleet.core.step.Safety``: margin,
        projection, rate, spread [m]); margin -1 (off) when disabled."""
        if not self.enabled:
            return (-1.0, 0.0, 0.0, 0.0)
        return (self.contact_margin_m, self.projection_m, self.barrier_rate, spread)

    def reach(self, speed: float, seconds: float) -> float:
        """How far [m] a body moving at ``speed`` [m/s] may get in ``seconds`` [s] with
        speeds changing by at most ``max_accel_m_s2``."""
        return abs(speed) * seconds + 0.5 * self.max_accel_m_s2 * seconds * seconds

    def own_spread(self, speed: float) -> float:
        """This robot's uncertainty [m] at the instant its command acts when it decides on
        its *measured* pose (no prediction: ``robot_agent.logic.decide`` without
        ``own_spread``): pose error plus the motion of up to ``max_latency_s`` of its
        commands in flight. The agent decides on its prediction instead
        (``robot_agent.prediction.predict_own``: a smaller spread)."""
        return self.pose_error_m + self.reach(speed, self.max_latency_s)

    def batch_spread(self) -> float:
        """The spread [m] the batch simulator (the planner's rollouts) gives every robot: a
        standing robot's pose error and what it may start to do within latency and link
        delay (the batch has no command latency of its own)."""
        return self.pose_error_m + self.reach(0.0, self.link_delay_s + self.max_latency_s)

    def measured_peer_spread(self, speed: float, reported_s: float, measured_s: float) -> float:
        """A peer's uncertainty [m] around its measured pose when it is known when that pose
        was measured (``measured_s`` [s] ago: its agent's reading on this session, or the
        send of a state whose send time is known -- synchronised clocks, a simulated link,
        this session's own agents) and when the state reporting ``speed`` [m/s] was sent
        (``reported_s`` [s] ago at most): its pose error and the motion it may make from
        the measurement until this robot's command acts, at most ``max_latency_s`` from
        now, starting at the speed the report allows by then. The link-delay bound of
        :meth:`peer_spread` is not needed: the measurement's age is known."""
        measured_s, reported_s = max(measured_s, 0.0), max(reported_s, 0.0)
        start = abs(speed) + self.max_accel_m_s2 * max(reported_s - measured_s, 0.0)
        return self.pose_error_m + self.reach(start, measured_s + self.max_latency_s)

    def peer_spread(self, speed: float, silent_s: float) -> float:
        """A peer's uncertainty [m] around its measured pose (reported ``speed`` [m/s],
        heard ``silent_s`` [s] ago) when its state carries no prediction (an older release)
        or it is stale: its pose error and the motion it may make from its measurement
        until this robot's command acts (``robot_agent.prediction.peer_spread`` otherwise).
        The silence counts until ``peer_stale_s``; a peer silent longer has stopped (class
        docstring) and is a standing obstacle with a standing robot's spread."""
        if silent_s > self.peer_stale_s:
            return self.pose_error_m + self.reach(0.0, self.link_delay_s + self.max_latency_s)
        seconds = self.link_delay_s + self.max_latency_s + max(silent_s, 0.0)
        return self.pose_error_m + self.reach(speed, seconds)


DEFAULT_TOLERANCE = Tolerance()
"""The paper's tight tolerance (comparative cases I and II): 0.05 m, 0.02 rad."""

UNLIMITED = RobotProfile(max_wheel_speed=math.inf)
"""Robot with no wheel-speed limit, as in the paper's simulations."""
