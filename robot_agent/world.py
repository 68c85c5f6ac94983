"""What a robot knows about the others: peers' last states and the static obstacles.

:class:`WorldView` is fed by Zenoh callbacks (any thread) and read by control loops. One
view can serve many agents sharing a session (``sim_agent.fleet``): every state is decoded
once instead of once per agent. Peers are never forgotten: a robot whose state stops
arriving stays an obstacle at its last pose.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from fleet.control import FloatArray
from fleet.wire import Decoder, Keys, Obstacle, ObstacleSet, RobotState
from robot_agent.logic import obstacle_arrays

_log = logging.getLogger(__name__)


class CallbackGuard:
    """Wraps Zenoh callbacks: an exception is caught, counted and logged, never lost."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._lock = threading.Lock()
        self.errors = 0

    def wrap(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        def guarded(arg: Any) -> None:
            try:
                fn(arg)
            except Exception:
                with self._lock:
                    self.errors += 1
                    count = self.errors
                if count <= 10 or count % 1000 == 0:
                    _log.exception("%s: callback failed (%d so far)", self.name, count)

        return guarded


class WorldView:
    """Thread-safe table of peer states (by robot id) and the static obstacle set."""

    def __init__(self, keys: Keys, decoder: Decoder | None = None) -> None:
        self.keys = keys
        self.decoder = decoder or Decoder("world")
        self.guard = CallbackGuard("world")
        self._lock = threading.Lock()
        self._states: dict[str, RobotState] = {}
        self._obstacles: list[Obstacle] = []
        self._obstacle_arrays: tuple[FloatArray, FloatArray] = obstacle_arrays([])
        self._rows: dict[str, int] = {}  # robot id -> row of _positions
        self._positions: FloatArray = np.zeros((16, 2))
        self._handles: list[Any] = []
        #: time.monotonic() of the last valid message from the network (link evidence)
        self.last_heard = float("-inf")

    # -- data (pure, thread-safe) -------------------------------------------------------
    def update_state(self, state: RobotState) -> None:
        """Keep the newest state of a robot (by ``seq``, so reordering cannot roll back)."""
        with self._lock:
            old = self._states.get(state.robot_id)
            if old is not None and state.seq <= old.seq and state.stamp <= old.stamp:
                return
            self._states[state.robot_id] = state
            row = self._rows.get(state.robot_id)
            if row is None:
                row = self._rows[state.robot_id] = len(self._rows)
                if row >= self._positions.shape[0]:
                    self._positions = np.concatenate(
                        [self._positions, np.zeros_like(self._positions)]
                    )
            self._positions[row] = (state.pose.x, state.pose.y)

    def set_obstacles(self, obstacles: ObstacleSet) -> None:
        arrays = obstacle_arrays(obstacles.obstacles)
        with self._lock:
            self._obstacles = list(obstacles.obstacles)
            self._obstacle_arrays = arrays

    def states(self) -> dict[str, RobotState]:
        with self._lock:
            return dict(self._states)

    def obstacles(self) -> tuple[FloatArray, FloatArray]:
        """Static obstacle centres (K, 2) and influence radii (K,) [m]."""
        with self._lock:
            return self._obstacle_arrays

    def peer_positions(self, exclude: str) -> FloatArray:
        """Last known centres (M, 2) [m] of every robot except ``exclude``."""
        with self._lock:
            n = len(self._rows)
            own = self._rows.get(exclude)
            if own is None:
                return self._positions[:n].copy()
            return np.delete(self._positions[:n], own, axis=0)

    # -- Zenoh edge -----------------------------------------------------------------------
    def _on_state(self, sample: Any) -> None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None:
            return
        if self.keys.robot_of(str(sample.key_expr)) != state.robot_id:
            self.decoder.drop("key_mismatch", f"{state.robot_id} on {sample.key_expr}")
            return
        self.last_heard = time.monotonic()
        self.update_state(state)

    def _on_obstacles(self, sample: Any) -> None:
        obstacles = self.decoder.decode(ObstacleSet, sample.payload.to_bytes())
        if obstacles is not None:
            self.last_heard = time.monotonic()
            self.set_obstacles(obstacles)

    def _on_obstacle_reply(self, reply: Any) -> None:
        if reply.ok is not None:
            self._on_obstacles(reply.ok)

    def attach(self, session: Any) -> None:
        """Subscribe to remote robot states and the obstacles; query obstacles (late joiner)."""
        import zenoh

        # Remote states only: agents on this session put their own states straight into
        # the view (RobotAgent._publish), so a process simulating N robots does not decode
        # its own N x rate states again.
        self._handles.append(
            session.declare_subscriber(
                self.keys.all_states,
                self.guard.wrap(self._on_state),
                allowed_origin=zenoh.Locality.REMOTE,
            )
        )
        self._handles.append(
            session.declare_subscriber(self.keys.obstacles, self.guard.wrap(self._on_obstacles))
        )
        # Non-blocking: replies (if the fleet service is up) arrive on a callback.
        session.get(self.keys.obstacles, self.guard.wrap(self._on_obstacle_reply), timeout=5.0)

    def detach(self) -> None:
        """Undeclare the subscribers (idempotent)."""
        handles, self._handles = self._handles, []
        for handle in handles:
            try:
                handle.undeclare()
            except Exception:  # session already closed: nothing left to undeclare
                _log.debug("undeclare failed", exc_info=True)
