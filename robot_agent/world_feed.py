"""Zenoh edge of a :class:`~robot_agent.world.WorldView`: peers' states and the obstacles.

:class:`WorldFeed` subscribes to the peer stream of the cells around the robots it feeds
(fleet/core/wire.py, "State streams") and to the obstacle set (and queries it once, for a
late joiner), decodes with drop counters, and writes into the view. Each agent reports its
position every tick (:meth:`WorldFeed.follow`); when a robot enters another cell the feed
subscribes to the new cells of its 3 x 3 block *before* it undeclares the ones no robot
needs any more, so a peer within reach is never unheard; and it queries each new cell for
the robots there, replayed by the fleet service with their age, so one that publishes
nothing any more (dead or cut off) is known too (fleet/core/wire.py, "Replay of last
states"). A feed shared by many agents (a simulated fleet on one session) subscribes to
the union of their blocks, each cell once.
Its :attr:`WorldFeed.last_heard` is the link monitor's evidence that the network is alive.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

from fleet.core.wire import Cell, Keys, ObstacleSet, RobotState, cells_around, parse_age
from fleet.io.decoder import CallbackGuard, Decoder
from robot_agent.world import WorldView

_log = logging.getLogger(__name__)


class WorldFeed:
    """Feeds ``world`` from a Zenoh session: :meth:`attach`, then :meth:`detach`."""

    def __init__(
        self,
        world: WorldView,
        keys: Keys,
        decoder: Decoder | None = None,
        *,
        upstream: WorldFeed | None = None,
        clock_sync_s: float | None = None,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        self.world = world
        #: [s] robots' wall clocks agree within this (``SafetyConfig.clock_sync_s``): a
        #: state's send time is then its stamp, give or take that; None: unknown.
        self.clock_sync_s = clock_sync_s
        self._wall = wall_clock
        self.upstream = upstream  # a shared feed that subscribes for this one (never attached)
        self.keys = keys
        self.decoder = decoder or Decoder("world")
        self.guard = CallbackGuard("world")
        self._handles: list[Any] = []
        self._session: Any = None
        self._lock = threading.Lock()  # the cell bookkeeping (never held across Zenoh calls)
        self._cell_of: dict[str, Cell] = {}  # robot -> the cell its block was taken at
        self._needed: Counter[Cell] = Counter()  # cell -> robots whose block holds it
        self._cells: dict[Cell, Any] = {}  # cell -> its subscriber
        self.resubscriptions = 0  # times a robot's block moved
        #: time.monotonic() of the last valid message from the network (link evidence)
        self.last_heard = float("-inf")

    @property
    def cells(self) -> frozenset[Cell]:
        """The cells whose peer stream this feed is subscribed to."""
        with self._lock:
            return frozenset(self._cells)

    def follow(self, robot_id: str, x: float, y: float) -> None:
        """A robot this feed serves stands at (x, y) [m, world frame]: hear every peer
        within one cell size of it (its 3 x 3 block of cells). Cheap when it stays in its
        cell; called by the robot's control loop each tick."""
        if self.upstream is not None:
            self.upstream.follow(robot_id, x, y)
        cell = self.keys.cell(x, y)
        with self._lock:
            old = self._cell_of.get(robot_id)
            if old == cell:
                return
            self._cell_of[robot_id] = cell
            add = self._block(cell)
            drop = self._block(old) if old is not None else frozenset()
            self._needed.update(add)
            self._needed.subtract(drop)
            gone = [c for c in drop if self._needed[c] <= 0]
            for c in gone:
                del self._needed[c]
            new = [c for c in add if c not in self._cells]
            session = self._session
            self.resubscriptions += 1
        if session is None:
            return
        self._subscribe(session, new)  # new cells first: no gap at a border
        self._unsubscribe(gone)

    def unfollow(self, robot_id: str) -> None:
        """A robot this feed served is gone: release its block."""
        if self.upstream is not None:
            self.upstream.unfollow(robot_id)
        with self._lock:
            old = self._cell_of.pop(robot_id, None)
            if old is None:
                return
            drop = self._block(old)
            self._needed.subtract(drop)
            gone = [c for c in drop if self._needed[c] <= 0]
            for c in gone:
                del self._needed[c]
        self._unsubscribe(gone)

    def _block(self, cell: Cell) -> frozenset[Cell]:
        """The cells meeting the square of half-width one cell size around any point of
        ``cell`` (taken at its centre, so the same block every time): its 3 x 3 block."""
        c = self.keys.cell_m
        return cells_around((cell[0] + 0.5) * c, (cell[1] + 0.5) * c, c, c)

    def _subscribe(self, session: Any, cells: list[Cell]) -> None:
        import zenoh

        for cell in cells:
            handle = session.declare_subscriber(
                self.keys.cell_states(cell),
                self.guard.wrap(self._on_state),
                allowed_origin=zenoh.Locality.REMOTE,
            )
            with self._lock:
                stale = self._cells.get(cell)
                self._cells[cell] = handle
            if stale is not None:
                _undeclare(stale)
            # Non-blocking, after the subscriber: a live robot's stream is newer than any
            # replay and wins (WorldView.update_state keeps the newest).
            session.get(
                self.keys.cell_states(cell), self.guard.wrap(self._on_state_reply), timeout=5.0
            )

    def _unsubscribe(self, cells: list[Cell]) -> None:
        handles = []
        with self._lock:
            for cell in cells:
                if self._needed[cell] <= 0 and cell in self._cells:
                    handles.append(self._cells.pop(cell))
        for handle in handles:
            _undeclare(handle)

    def _on_state(self, sample: Any) -> None:
        state = self._state_of(sample)
        if state is not None:
            self.last_heard = time.monotonic()
            self.world.update_state(state, sent_age_s=self._sent_age(state))

    def _sent_age(self, state: RobotState) -> tuple[float, float] | None:
        """How long ago [s] (most, least) ``state`` was sent, from its stamp when the clocks
        are synchronised; None when not, or when the stamp lies further ahead than the
        clocks may disagree (then the link-delay bound applies; counted)."""
        sync = self.clock_sync_s
        if sync is None:
            return None
        age = self._wall() - state.stamp
        if age + sync < 0.0:
            self.decoder.drop("stamp_ahead", f"{state.robot_id}: stamp {-age:.3f} s ahead")
            return None
        return age + sync, max(age - sync, 0.0)

    def _on_state_reply(self, reply: Any) -> None:
        """A robot's last state replayed by the service, heard ``age`` [s] ago."""
        sample = reply.ok
        if sample is None:
            return
        attachment = sample.attachment
        age = parse_age(None if attachment is None else attachment.to_bytes())
        if age is None:
            self.decoder.drop("replay_age", f"a replay on {sample.key_expr} without its age")
            return
        state = self._state_of(sample)
        if state is not None:
            self.world.update_state(state, age_s=age)

    def _state_of(self, sample: Any) -> RobotState | None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None:
            return None
        if self.keys.robot_of(str(sample.key_expr)) != state.robot_id:
            self.decoder.drop("key_mismatch", f"{state.robot_id} on {sample.key_expr}")
            return None
        return state

    def _on_obstacles(self, sample: Any) -> None:
        obstacles = self.decoder.decode(ObstacleSet, sample.payload.to_bytes())
        if obstacles is not None:
            self.last_heard = time.monotonic()
            self.world.set_obstacles(obstacles)

    def _on_obstacle_reply(self, reply: Any) -> None:
        if reply.ok is not None:
            self._on_obstacles(reply.ok)

    def attach(self, session: Any) -> None:
        """Subscribe to remote robot states and the obstacles; query obstacles (late joiner)."""

        # Remote states only (in _subscribe): agents on this session put their own states
        # straight into the view (RobotAgent._publish), so a process simulating N robots
        # does not decode its own N x rate states again.
        with self._lock:
            self._session = session
            cells = list(self._needed)
        self._subscribe(session, cells)
        self._handles.append(
            session.declare_subscriber(self.keys.obstacles, self.guard.wrap(self._on_obstacles))
        )
        # Non-blocking: replies (if the fleet service is up) arrive on a callback.
        session.get(self.keys.obstacles, self.guard.wrap(self._on_obstacle_reply), timeout=5.0)

    def detach(self) -> None:
        """Undeclare the subscribers (idempotent); the robots followed stay remembered."""
        with self._lock:
            self._session = None
            handles = [*self._handles, *self._cells.values()]
            self._handles, self._cells = [], {}
        for handle in handles:
            _undeclare(handle)


def _undeclare(handle: Any) -> None:
    try:
        handle.undeclare()
    except Exception:  # session already closed: nothing left to undeclare
        _log.debug("undeclare failed", exc_info=True)
