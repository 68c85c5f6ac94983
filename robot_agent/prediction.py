"""Where the robot and its peers will be when the robot's next command acts (pure).

A command decided now acts after the drive's latency, somewhere in the window
[lo, hi] of :class:`~robot_agent.latency.LatencyWindow`; the safety filter needs every body
where it is *then*. This module predicts, with what the robot cannot know as a radius
around each prediction (derivation: docs/safety.md, "Latency where it lives"):

* **Own pose** (:func:`predict_own`): the measured pose carried forward through the
  commands in flight (:class:`CommandLog`), each switched in at its send time plus the
  nominal latency, with the step's own Euler update (:func:`fleet.core.step.integrate_wheels`,
  the simulated drive's too), to the nominal instant the new command acts. Its spread
  (:attr:`OwnPrediction.spread`) bounds how far the true projected point may be from the
  predicted one at the instant the command really acts (any latency in the window): the
  pose error, the switches of the commands in flight each mistimed by up to the window's
  half-width, the wheels' actuation error, the heading errors those leave (rotating the
  rest of the way), and the motion between the nominal and the true instant.
* **What a robot tells its peers** (:meth:`OwnPrediction.ahead`): that predicted pose, its
  lead over the state's send time, the radius holding the true pose at that nominal
  instant once the new command is known, the heading error, and how fast its projected
  point may move under its commands in flight and the new one (:func:`point_speed`,
  actuation error included; ``fleet.core.wire.Ahead``).
* **A peer** (:func:`peer_spread`): around the pose the peer predicted for itself, a radius
  that grows with the time between that instant and this robot's window: the state's age
  (:func:`sent_window`: from its stamp when the clocks are synchronised within
  ``clock_sync_s``, else its arrival less the link-delay bound) and the window;
  or, when smaller, around its last measured pose (:func:`measured_spread`: in a lockstep
  simulation a peer's fresh reading is shared before anyone acts).
  A peer's filter may brake or swerve at any tick, so its direction after that instant is
  not extrapolated; its speed is bounded -- every agent caps the speed-ups of its
  commands' :func:`point_speed` at ``max_accel_m_s2`` (:func:`robot_agent.logic.cap_speed_up`)
  -- so the radius grows as v |t| + a t^2 / 2.

Frames and units: world frame, metres, radians, seconds on the agent's clock; the
*projected point* is ``SafetyConfig.projection_m`` ahead of the axle centre (the filter's).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from fleet.core.params import RobotProfile, SafetyConfig
from fleet.core.step import body_velocities, integrate_wheels
from fleet.core.wire import Ahead
from robot_agent.latency import LatencyWindow

Posture = tuple[float, float, float]


# -- commands in flight -------------------------------------------------------------------------
@dataclass(frozen=True)
class Sent:
    """A wheel command as the agent sent it: at [s, agent clock], right/left [rad/s]."""

    at: float
    right: float
    left: float


#: Before the first command the robot stood still (a drive starts stopped).
STANDING = Sent(-math.inf, 0.0, 0.0)


class CommandLog:
    """The wheel commands this robot sent, oldest first: those of the last ``span_s`` [s]
    and the newest one before them (it may still be turning); at most ``max_commands``."""

    def __init__(self, span_s: float, max_commands: int = 512) -> None:
        if not span_s > 0.0:
            raise ValueError(f"span must be positive, got {span_s}")
        self.span = float(span_s)
        self._sent: deque[Sent] = deque(maxlen=max_commands)

    def add(self, at: float, right: float, left: float) -> None:
        """The agent sent ``right``, ``left`` [rad/s] at ``at`` [s]."""
        sent = self._sent
        sent.append(Sent(float(at), float(right), float(left)))
        while len(sent) > 1 and sent[1].at < at - self.span:
            sent.popleft()

    def since(self, t: float) -> list[Sent]:
        """The commands sent at or after ``t`` [s], after the last one sent before it (or
        :data:`STANDING`): the one turning at ``t`` and those to come."""
        out: list[Sent] = []
        base = STANDING
        for sent in self._sent:
            if sent.at < t:
                base = sent
            else:
                out.append(sent)
        return [base, *out]

    @property
    def last(self) -> Sent:
        """The newest command (:data:`STANDING` before any)."""
        return self._sent[-1] if self._sent else STANDING

    def __len__(self) -> int:
        return len(self._sent)


def _segments(commands: list[Sent], shift: float, a: float, b: float) -> list[tuple[float, Sent]]:
    """(duration [s], command) pieces of [a, b] with command k turning from its send plus
    ``shift`` [s] until the next one's (``commands[0]`` turns before them all)."""
    k = 0
    while k + 1 < len(commands) and commands[k + 1].at + shift <= a:
        k += 1
    out: list[tuple[float, Sent]] = []
    for j in range(k, len(commands)):
        begin = a if j == k else commands[j].at + shift
        end = min(b, commands[j + 1].at + shift) if j + 1 < len(commands) else b
        if end > begin:
            out.append((end - begin, commands[j]))
        if end >= b:
            break
    return out


# -- own pose -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class OwnPrediction:
    """The robot's pose predicted for the nominal instant its next command acts, and what
    that prediction cannot know (module docstring).

    ``pose`` (x, y [m], theta [rad]): at ``at`` [s, agent clock] = decision time + nominal
    latency; ``spread`` [m]: radius around the projected point holding the true one at the
    instant the command really acts (the filter's own spread), and ``heading`` [rad] the
    heading's uncertainty then (the filter widens its cones by it). The rest feeds
    :meth:`ahead`: the last command sent, the total variations of u [m/s] and omega
    [rad/s] over the switches in flight, the fastest wheel speed ``wheel`` [m/s] (r (|right|
    + |left|) / 2) and :func:`point_speed` ``speed`` [m/s] in flight, the largest |u omega|
    ``turn``, the ``horizon`` [s] from the measurement to the window's end, the centre's
    ``path`` [m] over it and the Euler step ``period`` [s].
    """

    pose: Posture
    at: float
    spread: float
    heading: float
    window: LatencyWindow
    last: Sent
    tv_u: float
    tv_omega: float
    wheel: float
    speed: float
    turn: float
    horizon: float
    path: float
    period: float

    def ahead(
        self, right: float, left: float, profile: RobotProfile, safety: SafetyConfig, lead: float
    ) -> Ahead:
        """What peers are told once the new command (``right``, ``left`` [rad/s]) is known:
        the pose at the nominal instant, ``lead`` [s] after the state is sent, with the
        radius [m] and heading error [rad] holding the truth at that instant (the new
        command's switch mistimed too) and the fastest its projected point may move [m/s]."""
        r, b = profile.wheel_radius, profile.half_axle
        u, omega = body_velocities(right, left, r, b)
        u0, omega0 = body_velocities(self.last.right, self.last.left, r, b)
        tv_u = self.tv_u + abs(u - u0)
        tv_omega = self.tv_omega + abs(omega - omega0)
        wheel = max(self.wheel, _wheel_speed(right, left, r))
        turn = max(self.turn, abs(u * omega))
        delta = self.window.half_width
        heading, centre = _errors(
            safety, b, delta, tv_u, tv_omega, wheel * self.horizon, self.path,
            self.period * self.horizon * turn,
        )  # fmt: skip
        return Ahead(
            x=self.pose[0],
            y=self.pose[1],
            theta=self.pose[2],
            lead_s=max(lead, 0.0),
            spread_m=centre,
            heading_rad=heading,
            speed_m_s=max(self.speed, point_speed(u, omega, b, safety)),
        )


def _errors(
    safety: SafetyConfig, half_axle: float, delta: float, tv_u: float, tv_omega: float,
    wheel_path: float, path: float, euler: float,
) -> tuple[float, float]:  # fmt: skip
    """(heading [rad], centre [m]) error bounds of a prediction (docs/safety.md): switches
    mistimed by up to ``delta`` [s] (total variations ``tv_u``, ``tv_omega``), the wheels'
    relative actuation error over ``wheel_path`` [m], the heading error rotating the
    centre's ``path`` [m], and ``euler`` [m] for the Euler steps against the true arcs."""
    e = safety.actuation_error
    heading = safety.heading_error_rad + delta * tv_omega + e * wheel_path / half_axle
    centre = safety.pose_error_m + delta * tv_u + e * wheel_path + heading * path + euler
    return heading, centre


def _wheel_speed(right: float, left: float, wheel_radius: float) -> float:
    """r (|right| + |left|) / 2 [m/s]: bounds |u| and b |omega|, and the speed errors a
    relative wheel error gives (|du| <= e of it, |d omega| <= e of it / b)."""
    return 0.5 * wheel_radius * (abs(right) + abs(left))


def point_speed(u: float, omega: float, half_axle: float, safety: SafetyConfig) -> float:
    """The fastest [m/s] the projected point of a robot commanded (``u`` [m/s], ``omega``
    [rad/s]) may move: |u| + l |omega| plus what each wheel's relative actuation error e
    adds (|du| <= e s, |d omega| <= e s / b with s = |u| + b |omega|), l the projection."""
    ahead, e = safety.projection_m, safety.actuation_error
    s = abs(u) + half_axle * abs(omega)
    return abs(u) + ahead * abs(omega) + e * s * (1.0 + ahead / half_axle)


def _carried(
    pose: Posture, commands: list[Sent], shift: float, start: float, until: float,
    profile: RobotProfile, period: float,
) -> Posture:  # fmt: skip
    """``pose`` (measured at ``start`` [s]) carried to ``until`` [s] through ``commands``,
    each acting ``shift`` [s] after its send: Euler steps of at most ``period`` [s], the
    simulated drive's (:func:`~fleet.core.step.integrate_wheels`)."""
    r, b = profile.wheel_radius, profile.half_axle
    x, y, theta = pose
    for duration, sent in _segments(commands, shift, start, until):
        steps = max(1, math.ceil(duration / period - 1e-9))
        x, y, theta = integrate_wheels(
            x, y, theta, sent.right, sent.left, r, b, duration / steps, steps
        )
    return x, y, theta


def nominal_pose(
    pose: Posture,
    measured_at: float,
    now: float,
    log: CommandLog,
    window: LatencyWindow,
    profile: RobotProfile,
    period: float,
) -> Posture:
    """The robot's pose [m, m, rad] when a command sent at ``now`` [s] nominally acts:
    ``pose``, measured at ``measured_at`` [s], carried through the commands in flight
    (``log``) each acting the window's nominal latency after its send -- the pose of
    :func:`predict_own` without what it cannot know (the agent's latency compensation:
    the law decides on it, the safety filter keeps the measured pose and its spread)."""
    start = min(measured_at, now)
    commands = log.since(start - window.hi - period)
    return _carried(pose, commands, window.nominal, start, now + window.nominal, profile, period)


def predict_own(
    pose: Posture,
    measured_at: float,
    now: float,
    log: CommandLog,
    window: LatencyWindow,
    profile: RobotProfile,
    safety: SafetyConfig,
    period: float,
) -> OwnPrediction:
    """The robot's pose when a command sent at ``now`` [s] acts (module docstring).

    ``pose`` was measured at ``measured_at`` [s] (at most ``now``); ``log`` holds the
    commands sent before ``now``; ``period`` [s] is the longest Euler step (the control
    period, as the simulated drive integrates).
    """
    r, b = profile.wheel_radius, profile.half_axle
    ahead = safety.projection_m
    lam, delta = window.nominal, window.half_width
    start = min(measured_at, now)
    t_lo, t_nom, t_hi = now + window.lo, now + lam, now + window.hi
    commands = log.since(start - window.hi - period)

    # The prediction: Euler steps of at most one period through the nominal schedule.
    x, y, theta = _carried(pose, commands, lam, start, t_nom, profile, period)
    path = 0.0  # centre path length over [start, t_hi]
    before = after = 0.0  # projected point's path over [t_lo, t_nom] and [t_nom, t_hi]
    before_turn = after_turn = 0.0  # heading turned over the same [rad]
    t = start
    for duration, sent in _segments(commands, lam, start, t_hi):
        u, omega = body_velocities(sent.right, sent.left, r, b)
        speed = math.hypot(u, ahead * omega)
        end = t + duration
        early = max(0.0, min(end, t_nom) - max(t, t_lo))
        late = max(0.0, min(end, t_hi) - max(t, t_nom))
        before += speed * early
        after += speed * late
        before_turn += abs(omega) * early
        after_turn += abs(omega) * late
        path += abs(u) * duration
        t = end

    # What it cannot know (docs/safety.md): switches mistimed by up to delta, the wheels'
    # actuation error over the wheel path, the heading errors rotating the rest of the way.
    tv_u = tv_omega = wheel = fastest = turn = 0.0
    u0 = omega0 = 0.0
    for k, sent in enumerate(commands):
        wheel = max(wheel, _wheel_speed(sent.right, sent.left, r))
        u, omega = body_velocities(sent.right, sent.left, r, b)
        fastest = max(fastest, point_speed(u, omega, b, safety))
        turn = max(turn, abs(u * omega))
        if k > 0:
            tv_u += abs(u - u0)
            tv_omega += abs(omega - omega0)
        u0, omega0 = u, omega
    horizon = t_hi - start
    # An Euler step of h on an arc errs by at most |u omega| h^2 / 2 in position: the two
    # step sequences (prediction, truth) differ by at most h |u omega| per unit of time.
    euler = period * horizon * turn
    heading, centre = _errors(safety, b, delta, tv_u, tv_omega, wheel * horizon, path, euler)
    return OwnPrediction(
        pose=(x, y, theta),
        at=t_nom,
        spread=centre + ahead * heading + max(before, after),
        heading=heading + max(before_turn, after_turn),
        window=window,
        last=commands[-1],
        tv_u=tv_u,
        tv_omega=tv_omega,
        wheel=wheel,
        speed=fastest,
        turn=turn,
        horizon=horizon,
        path=path,
        period=period,
    )


# -- peers --------------------------------------------------------------------------------------
def peer_spread(
    ahead: Ahead,
    sent: tuple[float, float],
    now: float,
    window: LatencyWindow,
    safety: SafetyConfig,
) -> float:
    """Radius [m] around a peer's predicted projected point (its ``ahead`` posture) that
    holds the peer's true one at every instant this robot's command may act.

    The state carrying ``ahead`` was sent within ``sent`` (earliest, latest) [s, this
    robot's clock] (:func:`sent_window`); the peer's nominal instant is ``lead_s`` after
    that. ``now`` [s]: this robot's decision time, ``window``: its latency window.
    """
    early = now + window.lo - (sent[1] + ahead.lead_s)  # < 0: before the peer's instant
    late = now + window.hi - (sent[0] + ahead.lead_s)
    back, forward = max(0.0, -early), max(0.0, late)
    v = ahead.speed_m_s
    reach = max(v * back, v * forward + 0.5 * safety.max_accel_m_s2 * forward * forward)
    return ahead.spread_m + safety.projection_m * ahead.heading_rad + reach


def measured_spread(
    ahead: Ahead,
    sent: tuple[float, float],
    measured_at: float,
    now: float,
    window: LatencyWindow,
    safety: SafetyConfig,
) -> float:
    """Radius [m] around a peer's projected point as measured at ``measured_at`` [s, this
    robot's clock] (its agent's reading on this session, a lockstep simulation's), that
    holds the peer at every instant this robot's command may act: the pose errors and
    the reach, at the fastest speed the peer's last prediction (``ahead``, its state sent
    within ``sent``) allows by then. The smaller of this and :func:`peer_spread` is used
    (both hold the peer)."""
    end = now + window.hi
    speed = ahead.speed_m_s + safety.max_accel_m_s2 * max(0.0, end - (sent[0] + ahead.lead_s))
    reach = speed * max(0.0, end - measured_at)
    return safety.pose_error_m + safety.projection_m * safety.heading_error_rad + reach


def sent_window(
    heard: float, sent_age: tuple[float, float] | None, safety: SafetyConfig
) -> tuple[float, float]:
    """When [s] (earliest, latest) a state heard at ``heard`` [s] was sent: ``sent_age`` [s]
    (most, least) before it when known (synchronised clocks, a simulated link), else
    within ``link_delay_s`` before its arrival."""
    if sent_age is None:
        return heard - safety.link_delay_s, heard
    return heard - sent_age[0], heard - sent_age[1]
