"""Zenoh edge of a :class:`~robot_agent.world.WorldView`: peers' states and the obstacles.

:class:`WorldFeed` subscribes to every remote robot's state and to the obstacle set (and
queries it once, for a late joiner), decodes with drop counters, and writes into the view.
Its :attr:`WorldFeed.last_heard` is the link monitor's evidence that the network is alive.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from fleet.core.wire import Keys, ObstacleSet, RobotState
from fleet.io.decoder import CallbackGuard, Decoder
from robot_agent.world import WorldView

_log = logging.getLogger(__name__)


class WorldFeed:
    """Feeds ``world`` from a Zenoh session: :meth:`attach`, then :meth:`detach`."""

    def __init__(self, world: WorldView, keys: Keys, decoder: Decoder | None = None) -> None:
        self.world = world
        self.keys = keys
        self.decoder = decoder or Decoder("world")
        self.guard = CallbackGuard("world")
        self._handles: list[Any] = []
        #: time.monotonic() of the last valid message from the network (link evidence)
        self.last_heard = float("-inf")

    def _on_state(self, sample: Any) -> None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None:
            return
        if self.keys.robot_of(str(sample.key_expr)) != state.robot_id:
            self.decoder.drop("key_mismatch", f"{state.robot_id} on {sample.key_expr}")
            return
        self.last_heard = time.monotonic()
        self.world.update_state(state)

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
