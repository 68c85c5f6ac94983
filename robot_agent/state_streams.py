"""A robot's two state streams on Zenoh (fleet/core/wire.py, "State streams").

:class:`StateStreams` puts every state the agent publishes

* on the **peer stream**, ``cell/<cx>/<cy>/<id>``, every control tick, compact: the key
  follows the robot from cell to cell (a new publisher is declared when it enters one);
* on the **fleet-rate stream**, ``robot/<id>/state`` (the service's and tools' key), at
  ``Settings.fleet_rate_hz`` real time, phase-spread per robot so a fleet does not publish
  in bursts, and at once when what the service acts on changes (mode, task, revision,
  detail, faults): acknowledgements and e-stop confirmations do not wait for the rate.
  Encoded compact, or JSON with ``Settings.state_encoding = "json"`` (an older service).

Times are ``time.monotonic()`` seconds: the fleet rate is network load, real time also in a
time-scaled simulation.
"""

from __future__ import annotations

import logging
import time
import zlib
from collections.abc import Callable
from typing import Any

from fleet.core.wire import Cell, Keys, RobotState, encode, encode_state

_log = logging.getLogger(__name__)

#: What the service acts on: a change is published on the fleet-rate stream at once.
_Salient = tuple[object, ...]


def _salient(state: RobotState) -> _Salient:
    return (
        state.mode,
        state.task_id,
        state.revision,
        state.law,
        state.detail,
        tuple((e.code, e.level) for e in state.errors),
    )


class StateStreams:
    """Publishes one robot's states on both streams: :meth:`open`, :meth:`publish`,
    :meth:`close`. Called from the robot's control thread only."""

    def __init__(
        self,
        session: Any,
        keys: Keys,
        robot_id: str,
        *,
        fleet_rate_hz: float = 10.0,
        encoding: str = "compact",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.session = session
        self.keys = keys
        self.robot_id = robot_id
        self.fleet_key = keys.state(robot_id)  # validates the id
        self.fleet_period = 1.0 / fleet_rate_hz  # [s]
        self.json_fleet = encoding == "json"
        self.clock = clock
        self._fleet: Any = None
        self._peer: Any = None
        self._cell: Cell | None = None
        self._last: _Salient | None = None
        # Spread robots over the period: a fleet's fleet-rate states come as a steady stream.
        self._phase = self.fleet_period * (zlib.crc32(robot_id.encode()) % 1000) / 1000
        self._due = float("-inf")
        self.peer_puts = 0
        self.fleet_puts = 0
        self.cell_changes = 0

    @property
    def cell(self) -> Cell | None:
        """The cell the peer stream is published under (None before the first state)."""
        return self._cell

    def open(self) -> StateStreams:
        if self._fleet is None:
            self._fleet = self.session.declare_publisher(self.fleet_key)
            self._due = self.clock() + self._phase
        return self

    def publish(self, state: RobotState) -> None:
        """Put ``state`` on the peer stream, and on the fleet-rate stream when due or changed."""
        if self._fleet is None:
            return
        compact = encode_state(state)
        cell = self.keys.cell(state.pose.x, state.pose.y)
        if cell != self._cell:
            self._move_to(cell)
        self._peer.put(compact)
        self.peer_puts += 1
        now = self.clock()
        salient = _salient(state)
        due = now >= self._due
        if due or salient != self._last:
            if due:  # keep the cadence; after a stall start afresh rather than in a burst
                self._due = max(self._due + self.fleet_period, now)
            self._last = salient
            self._fleet.put(encode(state) if self.json_fleet else compact)
            self.fleet_puts += 1

    def _move_to(self, cell: Cell) -> None:
        old, self._peer = (
            self._peer,
            self.session.declare_publisher(self.keys.peer_state(self.robot_id, cell)),
        )
        self._cell = cell
        self.cell_changes += 1
        if old is not None:
            _undeclare(old)

    def close(self) -> None:
        """Undeclare both publishers (idempotent)."""
        fleet, peer, self._fleet, self._peer = self._fleet, self._peer, None, None
        self._cell = None
        for publisher in (peer, fleet):
            if publisher is not None:
                _undeclare(publisher)


def _undeclare(entity: Any) -> None:
    try:
        entity.undeclare()
    except Exception:  # session already closed: nothing left to undeclare
        _log.debug("undeclare failed", exc_info=True)
