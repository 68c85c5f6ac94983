"""``RobotAgent``: one robot's control loop on Zenoh, over a :class:`~robot_agent.drive.Drive`.

Each tick (default 50 Hz, ``Settings.control_rate_hz``, on the agent's monotonic clock) has
two phases: :meth:`RobotAgent.sense` reads the pose (and, from a drive that measures them,
the wheel speeds: :mod:`robot_agent.latency` learns the command-to-wheel latency from
them) and applies pending assignment messages; :meth:`RobotAgent.act` predicts the pose for
the instant its command will act (:func:`robot_agent.prediction.predict_own`, through the
commands in flight), decides on it with the pure :func:`robot_agent.logic.decide` (peers
where they predicted themselves, :meth:`robot_agent.world.WorldView.peer_bodies`), caps
the command's speed-up (:func:`robot_agent.logic.cap_speed_up`), commands the wheels and
publishes ``RobotState`` (stamped with the wall clock, with its prediction ``ahead``) through
:class:`~robot_agent.state_streams.StateStreams`: every tick on its grid cell's peer key,
and at the fleet rate (and on every change) on ``keys.state(id)``. Zenoh edges:

* liveliness token ``keys.alive(id)``, and right after it the robot's
  :class:`~fleet.core.wire.RobotDescription` (its profile, ``Settings.may_reverse`` and
  ``Settings.robot_model``) put on ``keys.description(id)``, with a queryable on that key
  answering with it until :meth:`RobotAgent.close` (``describe=False``: a robot of an
  older release, which publishes none);
* subscriber on ``keys.assignment(id)`` (park / cancel, decoded by ``wire.Decoder``:
  malformed payloads are dropped and counted, never reach the loop);
* subscribers on ``keys.control()`` (the whole fleet) and ``keys.control(id)`` (this robot):
  an operator's pause / resume / estop / release (:mod:`robot_agent.operator`), queued with
  the assignments and applied at the start of the next tick; while paused or e-stopped the
  tick commands zero wheels (``drive.stop()``) whatever the task says. The e-stop takes
  effect on the next tick (at most one control period later), not from the Zenoh callback:
  the Drive contract keeps every drive call on the control thread;
* the fencing term (:class:`fleet.core.wire.TermFence`): an assignment, cancel or service
  command with a term below the highest seen (a deposed leader's) is dropped on the control
  thread and counted in ``fence.dropped``; operator commands without a term always count;
* a :class:`~robot_agent.world_feed.WorldFeed` filling a :class:`~robot_agent.world.WorldView`
  with the states of peers in the cells around the robot (re-subscribed as it moves, told
  the robot's position each tick) and the obstacles (subscribed and queried once at
  start), owned or shared with other agents;
* a :class:`~robot_agent.link.LinkMonitor` (owned or shared): when the link to the router
  is lost (no router, or nothing heard for ``Settings.link_timeout_s``) an active task
  holds (``holding``, wheels stopped) and resumes when the link returns. A fleet *service*
  that is gone while the router and peers are still visible does not stop the robot.

Exceptions in callbacks are caught, counted and logged (``callback_errors``); an exception
in a tick stops the robot and is counted (``tick_errors``), the loop goes on. Each state says
why the robot stands still (``detail``) and lists its active faults (``errors``, see
:mod:`robot_agent.faults`).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fleet.core.params import SafetyConfig
from fleet.core.step import body_velocities
from fleet.core.wire import (
    CancelAssignment,
    ControlCommand,
    ParkAssignment,
    Pose,
    RobotDescription,
    RobotError,
    RobotMode,
    RobotState,
    TermFence,
    encode,
)
from fleet.io.decoder import CallbackGuard, Decoder
from fleet.io.settings import RobotSettings
from robot_agent.clock import Clock, MonotonicClock, run_periodic
from robot_agent.drive import Drive
from robot_agent.faults import FaultBook, current_faults
from robot_agent.latency import LatencyEstimator, LatencyWindow
from robot_agent.link import LinkMonitor
from robot_agent.logic import (
    NO_PEERS,
    AgentTask,
    AgentTaskStatus,
    TickResult,
    apply_assignment,
    cap_speed_up,
    decide,
)
from robot_agent.operator import OperatorLatch
from robot_agent.prediction import (
    CommandLog,
    OwnPrediction,
    Posture,
    nominal_pose,
    point_speed,
    predict_own,
)
from robot_agent.state_streams import StateStreams
from robot_agent.world import WorldView
from robot_agent.world_feed import WorldFeed

_log = logging.getLogger(__name__)
Inbound = ParkAssignment | CancelAssignment | ControlCommand
#: Modes in which the robot stands with nothing to do: a drive with ``release()`` may fall
#: silent there (an operator may teleop); every other stopped mode calls ``stop()`` each tick.
_AT_REST = (RobotMode.IDLE, RobotMode.ARRIVED)


def _predicts(safety: SafetyConfig) -> bool:
    """Whether the agent carries its pose through its commands in flight (``prediction``
    or ``compensate_latency``): it then logs its commands and measures its latency."""
    return safety.prediction or safety.compensate_latency


def _drive_faults(drive: Drive) -> list[tuple[str, str]]:
    """The drive's own holding faults (optional ``faults()``, e.g. the ros2 drive's pose_jump)."""
    faults = getattr(drive, "faults", None)
    return list(faults()) if faults is not None else []


@dataclass(frozen=True)
class AgentSnapshot:
    """What the agent last did (for tests, logs and status)."""

    pose: Pose
    mode: RobotMode
    task_id: str | None
    seq: int
    decision: TickResult
    errors: tuple[RobotError, ...] = ()


class RobotAgent:
    """Runs one robot: call :meth:`open` (declares on the session), then :meth:`run` or
    :meth:`start`, and :meth:`close` (also via ``with``). The session belongs to the caller.
    """

    def __init__(
        self,
        robot_id: str,
        drive: Drive,
        session: Any,
        settings: RobotSettings,
        *,
        clock: Clock | None = None,
        feed: WorldFeed | None = None,
        link: LinkMonitor | None = None,
        wall_clock: Callable[[], float] = time.time,
        describe: bool = True,
    ) -> None:
        self.keys = settings.keys()
        self.robot_id = robot_id
        self.keys.state(robot_id)  # validates the id
        self.drive = drive
        self.session = session
        self.settings = settings
        self.clock: Clock = clock or MonotonicClock()
        self.period = 1.0 / settings.control_rate_hz  # [s]
        self._wall = wall_clock
        self._owns_feed = feed is None
        self.feed = feed or WorldFeed(
            WorldView(), self.keys, clock_sync_s=settings.safety.clock_sync_s
        )
        self.world = self.feed.world
        self._owns_link = link is None
        self.link = link or LinkMonitor(
            session,
            self.keys,
            settings.link_timeout_s,
            check_router=(settings.zenoh_mode or "client") == "client",
            heard_elsewhere=lambda: self.feed.last_heard,
        )
        self.decoder = Decoder(f"agent {robot_id}")
        self.guard = CallbackGuard(f"agent {robot_id}")
        self._inbox: queue.SimpleQueue[Inbound] = queue.SimpleQueue()
        self._task: AgentTask | None = None
        self.operator = OperatorLatch(robot_id)
        #: Fencing term (``fleet.core.wire``): fleet messages below the highest term seen are
        #: dropped, counted in ``fence.dropped`` (a deposed leader's assignments and commands).
        self.fence = TermFence()
        self.faults = FaultBook()
        self._seq = 0
        self._pose = Pose(x=0.0, y=0.0, theta=0.0)
        safety = settings.safety
        #: The commands in flight (the prediction) and the latency learnt from the drive.
        self.commands = CommandLog(span_s=max(1.0, 4.0 * safety.max_latency_s))
        self.latency = LatencyEstimator(
            safety.max_latency_s,
            tolerance=2.0 * safety.actuation_error,  # a match: within twice the bound
            resolution_s=2 * self.period,
        )
        self._last_speed = 0.0  # [m/s] point_speed of the last command sent
        self._last_u = 0.0  # [m/s] bound on |u| in flight (own spread without prediction)
        self._reading: tuple[Pose, float, float] | None = None  # sensed (pose, stamp, now)
        self._failure: tuple[str, str] | None = None  # (phase, message) of a failed sense
        self.tick_errors = 0
        self.last: AgentSnapshot | None = None
        self._handles: list[Any] = []
        self.streams = StateStreams(
            session,
            self.keys,
            robot_id,
            fleet_rate_hz=settings.fleet_rate_hz,
            encoding=settings.state_encoding,
        )
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._opened = False
        self.description: RobotDescription | None = (
            RobotDescription.of(
                robot_id,
                settings.profile,
                may_reverse=settings.may_reverse,
                model=settings.robot_model,
            )
            if describe
            else None
        )
        self.description_queries = 0

    # -- Zenoh edges ----------------------------------------------------------------------
    @property
    def callback_errors(self) -> int:
        return self.guard.errors + self.feed.guard.errors

    def _on_assignment(self, sample: Any) -> None:
        message = self.decoder.decode_assignment(sample.payload.to_bytes())
        if message is None:
            return
        if message.robot_id != self.robot_id:
            self.decoder.drop("wrong_robot", f"{message.robot_id} on {sample.key_expr}")
            return
        self.submit(message)

    def _on_control(self, sample: Any) -> None:
        command = self.decoder.decode(ControlCommand, sample.payload.to_bytes())
        if command is None:
            return
        # A fleet-wide command comes on the fleet key, a robot's own on its key: anything
        # else (a command for robot B on robot A's key) is dropped and counted.
        robot = self.keys.robot_of(str(sample.key_expr))
        if command.robot_id != robot:
            self.decoder.drop("wrong_robot", f"{command.robot_id} on {sample.key_expr}")
            return
        self.submit(command)

    def _on_description_query(self, query: Any) -> None:
        """Answer a query on this robot's description key (a bad query is counted by the
        guard, never raised into Zenoh)."""
        if self.description is None:
            return
        query.reply(self.keys.description(self.robot_id), encode(self.description))
        self.description_queries += 1

    def submit(self, message: Inbound) -> None:
        """Queue an assignment or control message; applied at the start of the next tick
        (thread-safe)."""
        self._inbox.put(message)

    def open(self) -> RobotAgent:
        """Declare the publisher, liveliness token and subscribers on the session."""
        if self._opened:
            return self
        self._opened = True
        try:
            if self._owns_feed:
                self.feed.attach(self.session)
            if self._owns_link:
                self.link.attach()
            self.streams.open()
            self._handles.append(
                self.session.declare_subscriber(
                    self.keys.assignment(self.robot_id), self.guard.wrap(self._on_assignment)
                )
            )
            for key in (self.keys.control(), self.keys.control(self.robot_id)):
                self._handles.append(
                    self.session.declare_subscriber(key, self.guard.wrap(self._on_control))
                )
            self._handles.append(
                self.session.liveliness().declare_token(self.keys.alive(self.robot_id))
            )
            if self.description is not None:
                key = self.keys.description(self.robot_id)
                self.session.put(key, encode(self.description))
                self._handles.append(
                    self.session.declare_queryable(key, self.guard.wrap(self._on_description_query))
                )
        except BaseException:
            self.close()
            raise
        return self

    # -- control loop ---------------------------------------------------------------------
    def tick(self) -> AgentSnapshot | None:
        """One control step: :meth:`sense` then :meth:`act`."""
        self.sense()
        return self.act()

    def sense(self) -> None:
        """First phase of a tick: apply pending control commands and assignment messages, read
        the pose (time t) and put it in the world view shared with agents on this session.

        A lockstep simulation (``sim_agent.fleet``) senses every robot before any acts, so
        each decides on its peers' poses of the same time t, as the batch simulator does.
        """
        self._reading = None
        self._failure = None
        phase = "tick_error"
        try:
            self._apply_inbox(self.clock.now())
            phase = "drive_error"
            pose, stamp = self.drive.read_pose()
            wheel_speeds = getattr(self.drive, "wheel_speeds", None)
            if wheel_speeds is not None and _predicts(self.settings.safety):
                right, left, measured = wheel_speeds()
                self.latency.measured(measured, right, left)
            phase = "tick_error"
            now = self.clock.now()
            self._pose = pose
            self.world.update_position(self.robot_id, pose.x, pose.y, pose.theta, stamp)
            self.feed.follow(self.robot_id, pose.x, pose.y)
            self._reading = (pose, stamp, now)
        except Exception as exc:
            self._failure = self._tick_failed(phase, exc)

    def act(self) -> AgentSnapshot | None:
        """Second phase of a tick: predict the pose for the instant the command acts, decide
        on it (an operator's pause or e-stop overrides the decision), cap its speed-up,
        command the wheels and publish the state, its prediction and its faults."""
        reading, self._reading = self._reading, None
        failure = self._failure
        pose_age = float("nan")
        link_ok = True
        drive_faults: list[tuple[str, str]] = []
        decision: TickResult | None = None
        prediction: OwnPrediction | None = None
        window = self.latency.window()
        if reading is not None:
            pose, stamp, now = reading
            pose_age = now - stamp
            phase = "tick_error"
            try:
                link_ok = self.link.ok()
                safety, profile = self.settings.safety, self.settings.profile
                sent_at = self.clock.now()
                predicting = safety.prediction
                measured = pose.as_tuple()
                nominal: Posture | None = None
                if predicting:
                    prediction = predict_own(
                        measured, stamp, sent_at, self.commands, window, profile, safety,
                        self.period,
                    )  # fmt: skip
                elif safety.compensate_latency:
                    nominal = nominal_pose(
                        measured, stamp, sent_at, self.commands, window, profile, self.period
                    )
                override = self.operator.mode
                if override is not None:  # an operator's pause or e-stop: stand still, keep task
                    decision = TickResult(
                        mode=override, task=self._task, detail=self.operator.detail
                    )
                else:
                    active = self._task is not None and self._task.status is AgentTaskStatus.ACTIVE
                    peers = self.world.peer_bodies(
                        self.robot_id, safety, profile.radius, window if predicting else None
                    )
                    decision = decide(
                        prediction.pose if prediction is not None else measured,
                        pose_age,
                        self._task,
                        peers if active else NO_PEERS,
                        self.world.obstacles(),
                        profile,
                        self.settings.avoidance,
                        self.settings.pose_stale_s,
                        link_ok=link_ok if active else True,
                        now=now,
                        safety=safety,
                        speed=self._last_u,
                        period=self.period,
                        own_spread=None if prediction is None else prediction.spread,
                        own_heading=0.0 if prediction is None else prediction.heading,
                        nominal_pose=nominal,
                    )
                drive_faults = _drive_faults(self.drive)
                if drive_faults and override is None and decision.mode not in _AT_REST:
                    decision = TickResult(
                        mode=RobotMode.HOLDING, task=decision.task, detail=drive_faults[0][1]
                    )
                self._task = decision.task
                if predicting:  # no command's point speeds up faster than max_accel_m_s2
                    # (what peers assume of it): by a control period's worth per command.
                    limit = self._last_speed + safety.max_accel_m_s2 * self.period
                    decision = cap_speed_up(decision, limit, profile.half_axle, safety)
                # A bound on the speed of the commands in flight (falls at the drive's limit).
                fall = safety.max_accel_m_s2 * self.period
                self._last_u = max(abs(decision.u) if decision.moving else 0.0, self._last_u - fall)
                phase = "drive_error"
                release = getattr(self.drive, "release", None)
                if decision.moving:
                    self.drive.command_wheels(decision.right, decision.left)
                    self._sent(sent_at, decision.right, decision.left)
                elif decision.mode in _AT_REST and release is not None:
                    release()  # nothing to do: the drive may fall silent (teleop)
                    self._sent(sent_at, 0.0, 0.0)
                else:
                    self.drive.stop()  # held stopped for a reason: zero every tick
                    self._sent(sent_at, 0.0, 0.0)
            except Exception as exc:
                failure = self._tick_failed(phase, exc)
                decision = None
        if decision is None:  # sensing or acting failed (counted, logged, robot stopped)
            prediction = None
            drive_failed = failure is not None and failure[0] == "drive_error"
            what = "drive error" if drive_failed else "tick error"
            decision = TickResult(
                mode=self.operator.mode or RobotMode.HOLDING,
                task=self._task,
                detail=self.operator.detail or what,
            )
        faults = current_faults(
            pose_age=pose_age,
            pose_stale_s=self.settings.pose_stale_s,
            link_ok=link_ok,
            estop=self.operator.detail if self.operator.estop else None,
            failure=failure,
            drive=drive_faults,
            latency=self._latency_fault(window),
        )
        wall = self._wall()
        return self._publish(decision, self.faults.update(faults, wall), wall, prediction)

    def _sent(self, at: float, right: float, left: float) -> None:
        """Remember a wheel command sent at ``at`` [s]: in flight for the prediction, for the
        latency estimate, and for the next command's speed-up cap (with ``prediction`` on;
        off, and without latency compensation, the agent keeps nothing of it)."""
        if not _predicts(self.settings.safety):
            return
        self.commands.add(at, right, left)
        self.latency.commanded(at, right, left)
        profile = self.settings.profile
        u, omega = body_velocities(right, left, profile.wheel_radius, profile.half_axle)
        self._last_speed = point_speed(u, omega, profile.half_axle, self.settings.safety)

    def _latency_fault(self, window: LatencyWindow) -> str | None:
        if not window.exceeded:
            return None
        bound = self.settings.safety.max_latency_s
        return (
            f"command latency measured up to {window.hi:.3f} s, above max_latency_s "
            f"{bound:g} s: the filter uses the measured window"
        )

    def _tick_failed(self, phase: str, exc: Exception) -> tuple[str, str]:
        """Count and log an exception of a tick, stop the robot; the fault to report."""
        self.tick_errors += 1
        if self.tick_errors <= 10 or self.tick_errors % 1000 == 0:
            _log.exception("%s: tick failed (%d so far)", self.robot_id, self.tick_errors)
        self._safe_stop()
        what = "drive error" if phase == "drive_error" else "tick error"
        return (phase, f"{what}, robot stopped: {type(exc).__name__}: {exc}")

    def _apply_inbox(self, now: float) -> None:
        """Apply queued control commands and assignments, in arrival order."""
        while True:
            try:
                message = self._inbox.get_nowait()
            except queue.Empty:
                return
            if not self.fence.accept(message):
                _log.info(
                    "%s: dropped a %s of term %d (highest seen %d)",
                    self.robot_id,
                    message.kind,
                    message.term,
                    self.fence.highest,
                )
                continue
            if isinstance(message, ControlCommand):
                if self.operator.apply(message):
                    _log.info("%s: %s by %s", self.robot_id, message.command.value, message.issuer)
            else:
                self._task = apply_assignment(self._task, message, now)

    def _publish(
        self,
        decision: TickResult,
        errors: list[RobotError],
        wall: float,
        prediction: OwnPrediction | None = None,
    ) -> AgentSnapshot | None:
        task = decision.task
        a = task.assignment if task is not None else None
        snapshot = AgentSnapshot(
            pose=self._pose,
            mode=decision.mode,
            task_id=task.task_id if task is not None else None,
            seq=self._seq,
            decision=decision,
            errors=tuple(errors),
        )
        self.last = snapshot
        state = RobotState(
            robot_id=self.robot_id,
            seq=self._seq,
            stamp=wall,
            pose=self._pose,
            u=decision.u,
            omega=decision.omega,
            mode=decision.mode,
            task_id=snapshot.task_id,
            revision=a.revision if a is not None else 0,
            law=a.law if a is not None else None,
            goal=a.goal if a is not None else None,
            radius=self.settings.profile.radius,
            detail=decision.detail,
            errors=errors,
            ahead=None
            if prediction is None
            else prediction.ahead(
                decision.right,
                decision.left,
                self.settings.profile,
                self.settings.safety,
                lead=prediction.at - self.clock.now(),
            ),
        )
        self._seq += 1
        # Agents sharing this session see it without Zenoh, sent just now.
        self.world.update_state(state, sent_age_s=(0.0, 0.0))
        try:
            self.streams.publish(state)
        except Exception:
            self.tick_errors += 1
            _log.exception("%s: publishing state failed", self.robot_id)
        return snapshot

    def _safe_stop(self) -> None:
        try:
            self.drive.stop()
            self._sent(self.clock.now(), 0.0, 0.0)
        except Exception:
            _log.exception("%s: drive.stop() failed", self.robot_id)

    def run(self, stop: threading.Event | None = None) -> None:
        """Run the loop in real time in this thread until ``stop`` (or :meth:`close`).

        Simulations on a :class:`~robot_agent.clock.SteppedClock` call :meth:`tick`
        themselves instead (``sim_agent.fleet``).
        """
        self.open()
        event = stop or self._stop
        try:
            ticks, overruns = run_periodic(self.period, event, self.tick)
            if overruns:
                _log.warning("%s: %d of %d ticks overran", self.robot_id, overruns, ticks)
        finally:
            self._safe_stop()

    def start(self) -> RobotAgent:
        """Run the loop on a background thread (stopped by :meth:`close`)."""
        self.open()
        self._thread = threading.Thread(target=self.run, name=f"agent-{self.robot_id}")
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop the loop and the robot, undeclare everything (idempotent)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        self._thread = None
        self._safe_stop()
        handles, self._handles = self._handles, []
        self.streams.close()
        self.feed.unfollow(self.robot_id)
        for handle in reversed(handles):
            try:
                handle.undeclare()
            except Exception:
                _log.debug("undeclare failed", exc_info=True)
        if self._owns_link:
            self.link.detach()
        if self._owns_feed:
            self.feed.detach()

    def __enter__(self) -> RobotAgent:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()
