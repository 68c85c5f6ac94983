"""Many simulated robots in one process, sharing ONE Zenoh session (for scale).

Every robot is a full :class:`~robot_agent.agent.RobotAgent` (own publisher, liveliness
token, assignment subscriber) over a :class:`~sim_agent.drive.SimDrive`; they share one
:class:`~robot_agent.world.WorldView` (peer states decoded once) and one control thread
that ticks them all at the control rate on a common stepped clock (lockstep simulation:
all robots sense their poses of time t, then all act, as in the batch simulator).

Spawn layouts (:func:`spawn_layout`): ``random`` (uniform in the yard, kept apart, seeded),
``grid`` (rows centred on the origin), or a JSON file ``[{"id", "x", "y", "theta"}, ...]``.

Options for benchmarks: ``disturbances`` wraps every drive in a seeded
:class:`~sim_agent.disturbances.DisturbedDrive` (pose and actuation noise, command latency);
``link`` (:class:`~sim_agent.disturbances.LinkDisturbances`) delays and drops the robots'
states between them: each agent then has a view of its own, fed only by the copies of its
peers' states the :class:`~sim_agent.disturbances.DelayedLink` delivers at the start of a
tick (no more sharing of the poses just sensed), each with the simulated time it was sent
(the robots share one clock: synchronised clocks, ``SafetyConfig.clock_sync_s`` 0);
obstacles and states of robots in other processes still reach every view at once. Drives and
link come from :class:`~sim_agent.robots.SimRobots` (the same robots as the bench's
navground peers for the same seed). ``trace`` (a file path, :mod:`fleet.io.trace` format)
receives every robot's true pose and mode once per lockstep tick, after all agents ticked at
the same simulated time
(streamed: constant memory; flushed and closed by :meth:`SimFleet.close`).
"""

from __future__ import annotations

import json
import logging
import math
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fleet.core.wire import ObstacleSet, RobotMode, RobotState, validate_id
from fleet.io.settings import Settings
from fleet.io.trace import TraceHeader, TraceWriter
from robot_agent.agent import RobotAgent
from robot_agent.clock import SteppedClock, run_periodic
from robot_agent.link import LinkMonitor
from robot_agent.world import WorldView
from robot_agent.world_feed import WorldFeed
from sim_agent.disturbances import DelayedLink, Disturbances, DisturbedDrive, LinkDisturbances
from sim_agent.drive import SimDrive
from sim_agent.robots import SimRobots

_log = logging.getLogger(__name__)

#: Robots ticked back to back before the loop yields (see :meth:`SimFleet.run`).
SLICE = 50


@dataclass(frozen=True)
class Spawn:
    """Initial posture of one simulated robot: id, x, y [m], theta [rad] (world frame)."""

    robot_id: str
    x: float
    y: float
    theta: float = 0.0


def spawn_layout(
    layout: str,
    robots: int,
    *,
    seed: int | None = None,
    id_prefix: str = "robot-",
    yard: tuple[float, float, float, float] = (-10.0, 10.0, -10.0, 10.0),
    spacing: float = 1.5,
) -> list[Spawn]:
    """Initial postures for ``robots`` robots: ``random``, ``grid`` or a JSON file path.

    Ids are ``<id_prefix>1`` ... ``<id_prefix>N`` (a file brings its own ids).
    ``random`` keeps centres at least ``spacing`` [m] apart when the yard allows it.
    """
    if layout not in ("random", "grid"):
        return _spawn_file(Path(layout))
    if robots < 1:
        raise ValueError("--robots must be at least 1")
    ids = [validate_id(f"{id_prefix}{i}") for i in range(1, robots + 1)]
    xmin, xmax, ymin, ymax = yard
    rng = np.random.default_rng(seed)
    if layout == "grid":
        cols = math.ceil(math.sqrt(robots))
        rows = math.ceil(robots / cols)
        step = min(spacing, (xmax - xmin) / cols, (ymax - ymin) / rows)
        x0 = -(cols - 1) * step / 2
        y0 = -(rows - 1) * step / 2
        return [
            Spawn(rid, x0 + (i % cols) * step, y0 + (i // cols) * step, 0.0)
            for i, rid in enumerate(ids)
        ]
    placed: list[Spawn] = []
    for rid in ids:
        for attempt in range(200):
            x, y = float(rng.uniform(xmin, xmax)), float(rng.uniform(ymin, ymax))
            if attempt == 199 or all(math.hypot(x - s.x, y - s.y) >= spacing for s in placed):
                break
        placed.append(Spawn(rid, x, y, float(rng.uniform(-math.pi, math.pi))))
    return placed


def _spawn_file(path: Path) -> list[Spawn]:
    if not path.is_file():
        raise FileNotFoundError(f"spawn must be random, grid or a JSON file; not found: {path}")
    data = json.loads(path.read_text())
    if not isinstance(data, list) or not data:
        raise ValueError(f"{path}: expected a non-empty JSON list of {{id, x, y, theta}}")
    spawns = [
        Spawn(validate_id(str(e["id"])), float(e["x"]), float(e["y"]), float(e.get("theta", 0)))
        for e in data
    ]
    if len({s.robot_id for s in spawns}) != len(spawns):
        raise ValueError(f"{path}: duplicate robot ids")
    return spawns


class _HubView(WorldView):
    """The shared feed's view under link disturbances: obstacles and remote robots' states
    (other processes, over real Zenoh) go on to every agent's own view at once."""

    def __init__(self, clock: SteppedClock) -> None:
        super().__init__(clock.now)
        self.views: list[WorldView] = []

    def update_state(
        self, state: RobotState, age_s: float = 0.0, sent_age_s: tuple[float, float] | None = None
    ) -> None:
        super().update_state(state, age_s, sent_age_s)
        for view in self.views:
            view.update_state(state, age_s, sent_age_s)

    def set_obstacles(self, obstacles: ObstacleSet) -> None:
        super().set_obstacles(obstacles)
        for view in self.views:
            view.set_obstacles(obstacles)


class _LinkedView(WorldView):
    """One agent's own view under link disturbances: its own states leave through the link
    (one copy per peer), its peers' arrive only from it."""

    def __init__(
        self,
        owner: str,
        index: int,
        link: DelayedLink[tuple[RobotState, float]],
        clock: SteppedClock,
    ):
        super().__init__(clock.now)  # peers' silence in simulated seconds
        self.owner, self.index, self.link, self.clock = owner, index, link, clock

    def update_state(
        self, state: RobotState, age_s: float = 0.0, sent_age_s: tuple[float, float] | None = None
    ) -> None:
        super().update_state(state, age_s, sent_age_s)
        if state.robot_id == self.owner:  # with its send time: the robots share one clock
            self.link.send(self.index, (state, self.clock.now()), self.clock.now())


class SimFleet:
    """N simulated agents on one session, ticked by one thread.

    ``open()`` declares everything, ``run(stop)`` / ``start()`` ticks, ``close()`` undeclares
    (the session belongs to the caller). ``time_scale`` S paces one control period of
    simulated time every ``period / S`` real seconds (lockstep, see
    :class:`~robot_agent.clock.SteppedClock`).
    """

    def __init__(
        self,
        session: Any,
        settings: Settings,
        spawns: list[Spawn],
        *,
        time_scale: float = 1.0,
        noise_std: tuple[float, float, float] = (0.0, 0.0, 0.0),
        seed: int | None = None,
        disturbances: Disturbances | None = None,
        link: LinkDisturbances | None = None,
        trace: str | Path | None = None,
    ) -> None:
        self.session = session
        self.settings = settings
        if not time_scale > 0:
            raise ValueError(f"time scale must be positive, got {time_scale}")
        self.time_scale = float(time_scale)
        self.period = 1.0 / settings.control_rate_hz  # control period = Euler step [sim s]
        self.clock = SteppedClock()
        robots = SimRobots(
            disturbances or Disturbances(), link or LinkDisturbances(), noise_std
        ).build(
            [(s.x, s.y, s.theta) for s in spawns], settings.profile, seed, self.period, self.clock
        )
        self.robot_link = robots.link
        hub = _HubView(self.clock) if robots.link is not None else None
        self.world = hub or WorldView(self.clock.now)  # peers' silence in simulated seconds
        self.feed = feed = WorldFeed(self.world, settings.keys())
        self.link = LinkMonitor(  # one link per session, shared by its agents
            session,
            settings.keys(),
            settings.link_timeout_s,
            check_router=(settings.zenoh_mode or "client") == "client",
            heard_elsewhere=lambda: feed.last_heard,
        )
        self.drives: dict[str, SimDrive | DisturbedDrive] = {}
        self.agents: list[RobotAgent] = []
        self.views: list[WorldView] = []
        self.trace: TraceWriter | None = None
        for index, (spawn, drive) in enumerate(zip(spawns, robots.drives, strict=True)):
            self.drives[spawn.robot_id] = drive
            agent_feed = self.feed
            if hub is not None and robots.link is not None:
                view = _LinkedView(spawn.robot_id, index, robots.link, self.clock)
                hub.views.append(view)
                self.views.append(view)
                # never attached: the shared feed subscribes the cells the agent follows
                agent_feed = WorldFeed(view, settings.keys(), upstream=self.feed)
            self.agents.append(
                RobotAgent(
                    spawn.robot_id,
                    drive,
                    session,
                    settings,
                    clock=self.clock,
                    feed=agent_feed,
                    link=self.link,
                )
            )
        if trace is not None:
            self.trace = TraceWriter(trace, self.trace_header())
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._opened = False
        self.ticks = 0
        self.overruns = 0

    def agent(self, robot_id: str) -> RobotAgent:
        return next(a for a in self.agents if a.robot_id == robot_id)

    def open(self) -> SimFleet:
        if not self._opened:
            self._opened = True
            try:
                self.feed.attach(self.session)
                self.link.attach()
                for agent in self.agents:
                    agent.open()
            except BaseException:
                self.close()
                raise
        return self

    def _deliver(self) -> None:
        """Hand every agent the copies of its peers' states due by now (disturbed link)."""
        if self.robot_link is not None:
            now = self.clock.now()
            for receiver, (state, sent) in self.robot_link.deliver(now):
                self.views[receiver].update_state(state, sent_age_s=(now - sent, now - sent))

    def tick(self) -> None:
        """One control period in two phases: every agent senses its pose at sim time t
        (peers see it at once), then every agent acts; then t += period. So each robot
        decides on all its peers' poses of time t, as in the batch simulator. On a
        disturbed link, peers see only the states the link has delivered by t."""
        self._deliver()
        for agent in self.agents:
            agent.sense()
        for agent in self.agents:
            agent.act()
        self._record()
        self.clock.advance(self.period)

    def trace_header(self) -> TraceHeader:
        """The header of this fleet's trace file (ids, radii, period, mode names)."""
        radius = self.settings.profile.radius
        return TraceHeader(
            robots=tuple(a.robot_id for a in self.agents),
            radii=tuple(radius for _ in self.agents),
            period_s=self.period,
            modes=tuple(m.value for m in RobotMode),
        )

    def _record(self) -> None:
        """Every robot's true pose and mode at the current simulated time (to ``trace``)."""
        if self.trace is None:
            return
        trace = self.trace
        poses = [self.drives[a.robot_id].true_pose for a in self.agents]
        modes = [trace.mode_code(a.last.mode.value if a.last else None) for a in self.agents]
        trace.write(self.clock.now(), poses, modes)

    def _slices(self) -> list[list[RobotAgent]]:
        """Agents in groups of at most ``SLICE`` robots, ticked spread over the period."""
        return [self.agents[i : i + SLICE] for i in range(0, len(self.agents), SLICE)]

    def run(self, stop: threading.Event | None = None) -> None:
        """Tick every agent each control period until ``stop`` (or :meth:`close`).

        Every period starts with all agents sensing (see :meth:`tick`); large fleets then act
        in slices spread evenly over the period (every agent still decides at the same
        simulated time t), so their states leave as a steady stream, not one burst per period.
        """
        self.open()
        event = stop or self._stop
        slices = self._slices()
        position = 0

        def step() -> None:
            nonlocal position
            if position == 0:
                self._deliver()
                for agent in self.agents:
                    agent.sense()
            for agent in slices[position]:
                agent.act()
            position += 1
            if position == len(slices):
                position = 0
                self._record()
                self.clock.advance(self.period)

        try:
            # Catch up after short stalls (up to one control period behind).
            steps, overruns = run_periodic(
                self.period / self.time_scale / len(slices),
                event,
                step,
                max_lag=self.period / self.time_scale,
            )
            self.ticks, self.overruns = steps // len(slices), overruns
            if self.overruns:
                _log.warning(
                    "sim: %d of %d steps overran: ran slower than time scale %g",
                    overruns,
                    steps,
                    self.time_scale,
                )
        finally:
            for drive in self.drives.values():
                drive.stop()

    def start(self) -> SimFleet:
        self.open()
        self._thread = threading.Thread(target=self.run, name="sim-fleet")
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop ticking, stop every robot, undeclare everything (idempotent)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        self._thread = None
        for agent in self.agents:
            agent.close()
        self.link.detach()
        self.feed.detach()
        if self.trace is not None:
            self.trace.close()

    def __enter__(self) -> SimFleet:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()
