"""Leader election on PostgreSQL: a session-level advisory lock, a fencing term, a lease.

One :class:`Leadership` per service process, on a connection of its own:

* **Elect.** A standby tries ``pg_try_advisory_lock(LEADER_LOCK_KEY)`` every ``poll_s``. The
  winner raises the term in the one-row ``parkfleet_leader`` table (``term = term + 1``,
  with its name and API address, ``NOTIFY parkfleet_leader``) in one transaction, fences the
  store with it (:meth:`~fleet.service.store_postgres.PostgresTaskStore.fence`: from then on
  writes of any older term are refused), then calls ``on_elected(term)``.
* **Lease.** The leader pings its lock connection every ``lease_s / 4``. The session is set
  up so that the server drops it, and with it the lock, when the leader goes quiet:
  ``idle_session_timeout = lease_s`` and TCP keepalives / ``tcp_user_timeout`` of
  ``lease_s / 2``. A ping that fails (server gone, connection lost, a partition that
  outlasts the TCP timeout) makes the leader **step down at once**: the store is fenced with
  ``DEPOSED_TERM`` and ``on_deposed(reason)`` stops it commanding; it then competes again as
  a standby. So a leader that lost the database stops within ``lease_s`` of its last good
  ping, and no successor can be elected before the server dropped the old session
  (idle for ``lease_s``). A killed leader's lock goes as soon as its TCP connection closes.
* **Fence.** Clock rates or a stalled process can still break a lease; the term does not
  depend on time: the store refuses a deposed leader's writes, robots drop its commands
  (``fleet.core.wire`` "Fencing term").

Threads: one, ``fleet-leadership``; callbacks run on it (never with a lock of ours held).
"""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import psycopg

from fleet.service.clock import Clock, SystemClock
from fleet.service.roles import Role
from fleet.service.store_postgres import (
    DEPOSED_TERM,
    LEADER_CHANNEL,
    PostgresTaskStore,
    StoreUnavailable,
    connect,
)

_log = logging.getLogger(__name__)

#: The advisory lock whose holder leads (one per database).
LEADER_LOCK_KEY = 0x70666C74  # "pflt"


@dataclass(frozen=True)
class LeaderRecord:
    """The stored leadership: its term, the leader's name and API address (None: never)."""

    term: int
    leader: str | None
    address: str | None


def read_leader(store: PostgresTaskStore) -> LeaderRecord:
    """The leadership row as stored now."""
    rows = store.query("SELECT term, leader, address FROM parkfleet_leader WHERE id = 1")
    if not rows:
        return LeaderRecord(0, None, None)
    term, leader, address = rows[0]
    return LeaderRecord(int(term), leader, address)


class Leadership:
    """Elects this process (module docstring); ``role`` and ``term`` are its view."""

    def __init__(
        self,
        store: PostgresTaskStore,
        name: str,
        address: str,
        *,
        lease_s: float = 3.0,
        poll_s: float = 0.1,
        on_elected: Callable[[int], None],
        on_deposed: Callable[[str], None],
        clock: Clock | None = None,
    ) -> None:
        self.store = store
        self.name = name
        self.address = address
        self.lease_s = lease_s
        self.poll_s = poll_s
        self._on_elected = on_elected
        self._on_deposed = on_deposed
        self._clock: Clock = clock if clock is not None else SystemClock()
        self.role = Role.STANDBY
        self.term = 0
        self.elections = 0  # times this process was elected
        self.step_downs = 0
        self.last_error: str | None = None
        #: The stored leadership as last read by this process (a standby reads it each poll).
        self.seen_term = 0
        self.seen_leader: str | None = None
        self._conn: psycopg.Connection[Any] | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        store.fence(DEPOSED_TERM)  # a standby writes nothing

    def start(self) -> Leadership:
        self._thread = threading.Thread(target=self._run, name="fleet-leadership", daemon=True)
        self._thread.start()
        return self

    def _connect(self) -> psycopg.Connection[Any]:
        half_ms = max(1, int(self.lease_s * 500))
        conn = connect(
            self.store.dsn,
            timeout_s=self.lease_s,
            keepalives=1,
            keepalives_idle=max(1, int(self.lease_s / 2)),
            keepalives_interval=1,
            keepalives_count=1,
            tcp_user_timeout=half_ms,
            application_name=f"parkfleet {self.name}"[:63],
        )
        conn.execute(f"SET idle_session_timeout = {int(self.lease_s * 1000)}")
        return conn

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                if self.role is Role.LEADER:
                    self._renew()
                    self._stop.wait(self.lease_s / 4)
                else:
                    if not self._try_elect():
                        self._stop.wait(self.poll_s)
            except (StoreUnavailable, psycopg.Error) as exc:
                self.last_error = str(exc)
                self._drop_connection()
                if self.role is Role.LEADER:
                    self._step_down(f"lost PostgreSQL: {exc}")
                self._stop.wait(self.poll_s)
            except Exception:
                _log.exception("leadership loop failed")
                self._stop.wait(self.poll_s)

    def _try_elect(self) -> bool:
        if self._conn is None:
            self._conn = self._connect()
        conn = self._conn
        row = conn.execute(
            "SELECT pg_try_advisory_lock(%s), term, address FROM parkfleet_leader WHERE id = 1",
            (LEADER_LOCK_KEY,),
        ).fetchone()
        if row is not None:
            self.seen_term, self.seen_leader = int(row[1]), row[2]
        if not (row and row[0]):
            return False
        with conn.transaction():
            got = conn.execute(
                "UPDATE parkfleet_leader SET term = term + 1, leader = %s, address = %s,"
                " since = extract(epoch FROM now()) WHERE id = 1 RETURNING term",
                (self.name, self.address),
            ).fetchone()
            assert got is not None
            term = int(got[0])
            conn.execute("SELECT pg_notify(%s, %s)", (LEADER_CHANNEL, str(term)))
        self.term = self.seen_term = term
        self.seen_leader = self.address
        self.store.fence(term)
        self.role = Role.LEADER
        self.elections += 1
        _log.info("%s: elected leader, term %d", self.name, term)
        try:
            self._on_elected(term)
        except Exception as exc:
            _log.exception("taking over failed: stepping down")
            self._drop_connection()  # releases the lock
            self._step_down(f"take-over failed: {exc}")
        return True

    def _renew(self) -> None:
        if self._conn is None:
            raise StoreUnavailable("no leadership connection")
        self._conn.execute("SELECT 1")

    def _drop_connection(self) -> None:
        if self._conn is not None:
            with contextlib.suppress(psycopg.Error):
                self._conn.close()
            self._conn = None

    def _step_down(self, reason: str) -> None:
        self.store.fence(DEPOSED_TERM)
        self.role = Role.STANDBY
        self.step_downs += 1
        _log.warning("%s: stepped down from term %d: %s", self.name, self.term, reason)
        try:
            self._on_deposed(reason)
        except Exception:
            _log.exception("stepping down failed")

    def close(self) -> None:
        """Stop competing; a leader steps down (its lock goes with its connection)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        self._drop_connection()
        if self.role is Role.LEADER:
            self._step_down("closed")
