"""What a robot knows about the others: peers' last states and the static obstacles.

:class:`WorldView` is a thread-safe table, fed by :class:`robot_agent.world_feed.WorldFeed`
(Zenoh callbacks, any thread) and read by control loops. One view can serve many agents
sharing a session (``sim_agent.fleet``): every state is decoded once instead of once per
agent. Peers are never forgotten: a robot whose state stops arriving stays an obstacle at
its last pose.

Each peer is kept with its last measured pose and, when its state carried one, the pose it
predicted for itself (``RobotState.ahead``): :meth:`WorldView.peer_bodies` shows the safety
filter every peer there, with the radius of :func:`robot_agent.prediction.peer_spread`. A
peer without a prediction (or with ``safety.prediction`` off) is around its measured pose:
with :meth:`~fleet.core.params.SafetyConfig.measured_peer_spread` when its state's send time
is known, else with :meth:`~fleet.core.params.SafetyConfig.peer_spread` (the link-delay
bound); a peer silent ``peer_stale_s`` is a standing obstacle (``peer_spread``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

import numpy as np

from fleet.core.params import SafetyConfig
from fleet.core.types import FloatArray
from fleet.core.wire import Ahead, Obstacle, ObstacleSet, RobotState
from robot_agent.latency import LatencyWindow
from robot_agent.logic import obstacle_arrays
from robot_agent.prediction import measured_spread, peer_spread, sent_window

#: A peer's prediction as kept: the ``ahead`` of its newest state, when that state was
#: heard [s, the view's clock] and how long before that it was sent (most, least) [s], if
#: known (None: within the link-delay bound).
Prediction = tuple[Ahead, float, tuple[float, float] | None]


class WorldView:
    """Thread-safe table of peer states (by robot id) and the static obstacle set."""

    #: Columns of a peer row: x, y, theta [m, m, rad], body radius [m], |u| [m/s], when it
    #: was heard [s, ``clock``], when that pose was measured if it is an agent's own
    #: reading on this session (:meth:`update_position`; NaN when it came with a state),
    #: and when its newest state was sent at the earliest, if known (NaN: within the
    #: link-delay bound before it was heard).
    _COLUMNS = 8

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._lock = threading.Lock()
        self._clock = clock
        self._states: dict[str, RobotState] = {}
        self._obstacles: list[Obstacle] = []
        self._obstacle_arrays: FloatArray = obstacle_arrays([])
        self._rows: dict[str, int] = {}  # robot id -> row of _positions
        self._ids: list[str] = []  # robot id of each row
        self._positions: FloatArray = np.zeros((16, self._COLUMNS))
        self._ahead: dict[str, Prediction] = {}  # robot id -> its newest prediction

    def update_state(
        self, state: RobotState, age_s: float = 0.0, sent_age_s: tuple[float, float] | None = None
    ) -> None:
        """Keep the newest state of a robot (by ``seq``, so reordering cannot roll back);
        ``age_s`` [s]: how long before now it was heard (a state replayed by the service);
        ``sent_age_s`` [s]: how long before it was heard it was sent, at most and at least,
        when that is known (synchronised clocks, a simulated link, this session's own
        agents); None: anywhere within the link-delay bound."""
        with self._lock:
            old = self._states.get(state.robot_id)
            if old is not None and state.seq <= old.seq and state.stamp <= old.stamp:
                return
            self._states[state.robot_id] = state
            p = state.pose
            self._set_row(
                state.robot_id, (p.x, p.y, p.theta, state.radius, abs(state.u)), max(age_s, 0.0)
            )
            row = self._rows[state.robot_id]
            heard = float(self._positions[row, 5])  # as _set_row wrote it
            self._positions[row, 7] = math.nan if sent_age_s is None else heard - sent_age_s[0]
            if state.ahead is None:
                self._ahead.pop(state.robot_id, None)
            else:
                self._ahead[state.robot_id] = (state.ahead, heard, sent_age_s)

    def update_position(
        self, robot_id: str, x: float, y: float, theta: float, measured_at: float | None = None
    ) -> None:
        """A robot's posture as its agent on this session measured it at ``measured_at`` [s,
        the view's clock; None: now], before its state (with mode and speeds) is published:
        peers deciding now see it."""
        with self._lock:
            row = self._rows.get(robot_id)
            radius, speed = (0.0, 0.0) if row is None else self._positions[row, 3:5]
            self._set_row(robot_id, (x, y, theta, float(radius), float(speed)), 0.0)
            row = self._rows[robot_id]
            self._positions[row, 6] = self._clock() if measured_at is None else measured_at

    def _set_row(
        self, robot_id: str, values: tuple[float, float, float, float, float], age_s: float
    ) -> None:
        row = self._rows.get(robot_id)
        if row is None:
            row = self._rows[robot_id] = len(self._rows)
            self._ids.append(robot_id)
            if row >= self._positions.shape[0]:
                self._positions = np.concatenate([self._positions, np.zeros_like(self._positions)])
            self._positions[row, 7] = math.nan  # no state yet: its send time is not known
        self._positions[row, :5] = values
        self._positions[row, 5] = self._clock() - age_s
        self._positions[row, 6] = math.nan

    def set_obstacles(self, obstacles: ObstacleSet) -> None:
        arrays = obstacle_arrays(obstacles.obstacles)
        with self._lock:
            self._obstacles = list(obstacles.obstacles)
            self._obstacle_arrays = arrays

    def states(self) -> dict[str, RobotState]:
        with self._lock:
            return dict(self._states)

    def obstacles(self) -> FloatArray:
        """Static obstacles as the compiled step's rows (:func:`obstacle_arrays`)."""
        with self._lock:
            return self._obstacle_arrays

    def peer_positions(self, exclude: str) -> FloatArray:
        """Last known centres (M, 2) [m] of every robot except ``exclude``."""
        return self._peer_rows(exclude)[0][:, :2].copy()

    def _peer_rows(self, exclude: str) -> tuple[FloatArray, list[Prediction | None]]:
        """Rows of every robot but ``exclude`` and their predictions (with heard times)."""
        with self._lock:
            n = len(self._rows)
            ids = list(self._ids)
            own = self._rows.get(exclude)
            rows = self._positions[:n].copy()
            if own is not None:
                rows = np.delete(rows, own, axis=0)
                del ids[own]
            return rows, [self._ahead.get(robot) for robot in ids]

    def peer_bodies(
        self,
        exclude: str,
        safety: SafetyConfig,
        default_radius: float,
        window: LatencyWindow | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Every robot but ``exclude`` as the safety filter sees it: postures (3, M) (x, y,
        theta) and shapes (2, M) (body radius, spread [m]).

        With ``window`` (this robot's latency window, its command about to be sent now), a
        peer whose last state carried its prediction and that has not been silent
        ``peer_stale_s`` is at that prediction with
        :func:`~robot_agent.prediction.peer_spread`, or, when its agent's reading on this
        session gives a smaller radius, at that reading with
        :func:`~robot_agent.prediction.measured_spread`; any other (no prediction, no
        ``window``, or stale) at its last measured pose: with
        :meth:`SafetyConfig.measured_peer_spread` when its newest state's send time is known
        (synchronised clocks, a simulated link, an agent of this session) and it has not
        been silent ``peer_stale_s`` -- from that send, or from its agent's later reading
        on this session --, else with :meth:`SafetyConfig.peer_spread` of its speed and
        silence (the link-delay bound). A robot not yet described by a state (only measured
        on this session) gets ``default_radius`` [m]."""
        rows, predictions = self._peer_rows(exclude)
        now = self._clock()
        postures = np.ascontiguousarray(rows[:, :3].T)
        shapes = np.empty((2, rows.shape[0]))
        for k in range(rows.shape[0]):
            radius, speed, heard = rows[k, 3], rows[k, 4], rows[k, 5]
            shapes[0, k] = radius if radius > 0.0 else default_radius
            prediction = predictions[k]
            if window is not None and prediction is not None:
                ahead, heard_at, sent_age = prediction
                if now - heard_at <= safety.peer_stale_s:
                    sent = sent_window(heard_at, sent_age, safety)
                    spread = peer_spread(ahead, sent, now, window, safety)
                    measured_at = float(rows[k, 6])
                    if not math.isnan(measured_at):  # a fresh reading on this session
                        measured = measured_spread(ahead, sent, measured_at, now, window, safety)
                        if measured <= spread:
                            shapes[1, k] = measured
                            continue
                    postures[0, k], postures[1, k] = ahead.x, ahead.y
                    postures[2, k] = ahead.theta
                    shapes[1, k] = spread
                    continue
            silent, reported = now - float(heard), float(rows[k, 7])
            if math.isnan(reported) or silent > safety.peer_stale_s:
                shapes[1, k] = safety.peer_spread(float(speed), silent)
                continue
            measured = float(rows[k, 6])
            measured = reported if math.isnan(measured) else max(measured, reported)
            shapes[1, k] = safety.measured_peer_spread(float(speed), now - reported, now - measured)
        return postures, shapes
