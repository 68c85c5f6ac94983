"""What a robot knows about the others: peers' last states and the static obstacles.

:class:`WorldView` is a thread-safe table, fed by :class:`robot_agent.world_feed.WorldFeed`
(Zenoh callbacks, any thread) and read by control loops. One view can serve many agents
sharing a session (``sim_agent.fleet``): every state is decoded once instead of once per
agent. Peers are never forgotten: a robot whose state stops arriving stays an obstacle at
its last pose.
"""

from __future__ import annotations

import threading

import numpy as np

from fleet.core.types import FloatArray
from fleet.core.wire import Obstacle, ObstacleSet, RobotState
from robot_agent.logic import obstacle_arrays


class WorldView:
    """Thread-safe table of peer states (by robot id) and the static obstacle set."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._states: dict[str, RobotState] = {}
        self._obstacles: list[Obstacle] = []
        self._obstacle_arrays: tuple[FloatArray, FloatArray] = obstacle_arrays([])
        self._rows: dict[str, int] = {}  # robot id -> row of _positions
        self._positions: FloatArray = np.zeros((16, 2))

    def update_state(self, state: RobotState) -> None:
        """Keep the newest state of a robot (by ``seq``, so reordering cannot roll back)."""
        with self._lock:
            old = self._states.get(state.robot_id)
            if old is not None and state.seq <= old.seq and state.stamp <= old.stamp:
                return
            self._states[state.robot_id] = state
            self._set_position(state.robot_id, state.pose.x, state.pose.y)

    def update_position(self, robot_id: str, x: float, y: float) -> None:
        """A robot's position [m] as its agent on this session just measured it, before its
        state (with mode and speeds) is published: peers deciding now see it."""
        with self._lock:
            self._set_position(robot_id, x, y)

    def _set_position(self, robot_id: str, x: float, y: float) -> None:
        row = self._rows.get(robot_id)
        if row is None:
            row = self._rows[robot_id] = len(self._rows)
            if row >= self._positions.shape[0]:
                self._positions = np.concatenate([self._positions, np.zeros_like(self._positions)])
        self._positions[row] = (x, y)

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
