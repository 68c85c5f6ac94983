"""Task persistence on PostgreSQL (psycopg 3): the :class:`~fleet.service.store.TaskStore`
contract, shared by a leader and its standbys, with the fencing term checked in every write.

Tables as in the SQLite store (``tasks``, ``task_history``, ``service_state``) plus
``parkfleet_leader``: one row holding the current leadership **term**, the leader's name and
the address of its API (:mod:`fleet.service.leadership` raises the term when it is elected).

* **Fencing.** :meth:`PostgresTaskStore.fence` sets the term this process writes under. Every
  write transaction first reads the leader row ``FOR SHARE`` and raises :class:`Deposed` if
  the stored term is not this process's: the row lock orders each write against a new
  leader's ``UPDATE ... term = term + 1``, so once a successor's term is committed no write
  of the old leader can commit (a write that committed earlier was the old leader's by
  right). Unfenced (``fence(None)``, the default) writes are not checked: a lone service
  without election, or the contract tests. Each stored row records the term that wrote it.
* **Follow.** Every write also sends ``NOTIFY parkfleet_tasks, '<task id>'`` (delivered on
  commit only); a new term sends ``parkfleet_leader``. Standbys ``LISTEN``
  (:mod:`fleet.service.standby`).
* **Durability.** PostgreSQL commits with ``synchronous_commit`` as the server is set
  (``on`` by default: on disk on return). Concurrent writers use a few pooled connections, so
  the server's own group commit shares the fsyncs.
* **Faults.** An unreachable server at open raises :class:`StoreUnavailable` (a
  ``ConnectionError``: the CLI prints it and exits 2). A connection lost later fails that
  call with ``StoreUnavailable`` and is replaced on the next one.

Thread-safe: each call borrows a pooled connection (never two calls on one connection).
"""

from __future__ import annotations

import builtins
import queue
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

import psycopg

from fleet.core.tasks import Task, TaskStatus
from fleet.service.store import TaskCursor, list_query, robot_of

_FINAL = [s.value for s in TaskStatus if s.final]

#: Advisory lock key held (per transaction) while creating the schema, so two services
#: starting at once do not race on ``CREATE TABLE IF NOT EXISTS``.
SCHEMA_LOCK_KEY = 0x7061726B  # "park"

TASKS_CHANNEL = "parkfleet_tasks"
LEADER_CHANNEL = "parkfleet_leader"

_SCHEMA = """
-- id in byte order ("C"), as SQLite and Python compare it, whatever the database's locale:
-- the task list's cursor is (created_at, id).
CREATE TABLE IF NOT EXISTS tasks (
    id TEXT COLLATE "C" PRIMARY KEY,
    status TEXT NOT NULL,
    robot_id TEXT,
    idempotency_key TEXT UNIQUE,
    created_at DOUBLE PRECISION NOT NULL,
    updated_at DOUBLE PRECISION NOT NULL,
    term BIGINT NOT NULL DEFAULT 0,
    body TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS tasks_page ON tasks (created_at, id);
CREATE INDEX IF NOT EXISTS tasks_status_page ON tasks (status, created_at, id);
CREATE INDEX IF NOT EXISTS tasks_robot_page ON tasks (robot_id, created_at, id);
CREATE INDEX IF NOT EXISTS tasks_finished ON tasks (status, updated_at);
CREATE TABLE IF NOT EXISTS task_history (
    seq BIGSERIAL PRIMARY KEY,
    task_id TEXT NOT NULL,
    at DOUBLE PRECISION NOT NULL,
    event TEXT NOT NULL,
    status TEXT NOT NULL,
    term BIGINT NOT NULL DEFAULT 0,
    body TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS task_history_task ON task_history (task_id);
CREATE TABLE IF NOT EXISTS service_state (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS parkfleet_leader (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    term BIGINT NOT NULL,
    leader TEXT,
    address TEXT,
    since DOUBLE PRECISION
);
INSERT INTO parkfleet_leader (id, term) VALUES (1, 0) ON CONFLICT (id) DO NOTHING;
"""

_T = TypeVar("_T")

#: The term a deposed process writes under: never stored, so every fenced write fails.
DEPOSED_TERM = -1


class StoreUnavailable(ConnectionError):
    """PostgreSQL cannot be reached (or the connection was lost); the reason says which."""


class Deposed(RuntimeError):
    """A write under a term that is no longer the stored one: a newer leader exists."""

    def __init__(self, mine: int, stored: int) -> None:
        super().__init__(f"deposed: this service writes under term {mine}, the store's is {stored}")
        self.mine = mine
        self.stored = stored


def connect(dsn: str, *, timeout_s: float = 5.0, **kwargs: Any) -> psycopg.Connection[Any]:
    """One connection to ``dsn`` (autocommit unless told), or :class:`StoreUnavailable`
    naming the server (without the password) and why."""
    kwargs.setdefault("autocommit", True)
    try:
        return psycopg.connect(dsn, connect_timeout=max(1, round(timeout_s)), **kwargs)
    except psycopg.Error as exc:
        raise StoreUnavailable(f"PostgreSQL unreachable at {redact(dsn)}: {exc}".strip()) from exc


def redact(dsn: str) -> str:
    """``dsn`` without its password (for messages and logs)."""
    try:
        info = psycopg.conninfo.conninfo_to_dict(dsn)
    except psycopg.ProgrammingError:
        return "<unparsable DSN>"
    info.pop("password", None)
    host, port, db = info.get("host", "localhost"), info.get("port", "5432"), info.get("dbname")
    return f"postgresql://{host}:{port}/{db or ''}"


class PostgresTaskStore:
    """PostgreSQL :class:`~fleet.service.store.TaskStore` with fenced writes (module
    docstring); ``pool_size`` connections are opened on demand, ``timeout_s`` bounds a
    connect [s]."""

    def __init__(self, dsn: str, *, pool_size: int = 4, timeout_s: float = 5.0) -> None:
        self.dsn = dsn
        self.timeout_s = timeout_s
        self._pool: queue.LifoQueue[psycopg.Connection[Any] | None] = queue.LifoQueue()
        for _ in range(pool_size):
            self._pool.put(None)  # a free slot: connect when first borrowed
        self._term: int | None = None
        self._closed = False
        with self._connection() as db, db.transaction():
            db.execute("SELECT pg_advisory_xact_lock(%s)", (SCHEMA_LOCK_KEY,))
            db.execute(_SCHEMA)

    # -- connections ----------------------------------------------------------------------
    @contextmanager
    def _connection(self) -> Iterator[psycopg.Connection[Any]]:
        if self._closed:
            raise RuntimeError("task store is closed")
        conn = self._pool.get()
        try:
            if conn is None or conn.closed:
                conn = connect(self.dsn, timeout_s=self.timeout_s)
            yield conn
        except psycopg.OperationalError as exc:
            if conn is not None:
                conn.close()
            conn = None
            raise StoreUnavailable(
                f"PostgreSQL connection lost ({redact(self.dsn)}): {exc}"
            ) from exc
        finally:
            if (
                conn is not None
                and conn.info.transaction_status != psycopg.pq.TransactionStatus.IDLE
            ):
                conn.close()  # never hand a connection in a transaction to the next caller
                conn = None
            if conn is not None and self._closed:
                conn.close()  # closed meanwhile: the slot stays empty
            self._pool.put(conn)

    def fence(self, term: int | None) -> None:
        """Write under ``term`` from now on (``None``: unchecked; ``DEPOSED_TERM``: refused)."""
        self._term = term

    @property
    def term(self) -> int | None:
        return self._term

    def _write(self, op: Callable[[psycopg.Connection[Any], int], _T]) -> _T:
        """Run ``op(db, term)`` in one transaction after the fencing check."""
        term = self._term
        with self._connection() as db, db.transaction():
            if term is not None:
                row = db.execute(
                    "SELECT term FROM parkfleet_leader WHERE id = 1 FOR SHARE"
                ).fetchone()
                stored = int(row[0]) if row is not None else 0
                if stored != term:
                    raise Deposed(term, stored)
            return op(db, max(term or 0, 0))

    def _upsert(
        self, db: psycopg.Connection[Any], term: int, task: Task, key: str | None, event: str
    ) -> None:
        body = task.model_dump_json()
        db.execute(
            "INSERT INTO tasks (id, status, robot_id, idempotency_key, created_at, updated_at,"
            " term, body) VALUES (%s, %s, %s, %s, %s, %s, %s, %s) ON CONFLICT (id) DO UPDATE SET"
            " status=excluded.status, robot_id=excluded.robot_id,"
            " updated_at=excluded.updated_at, term=excluded.term, body=excluded.body",
            (task.id, task.status.value, robot_of(task), key, task.created_at, task.updated_at,
             term, body),
        )  # fmt: skip
        db.execute(
            "INSERT INTO task_history (task_id, at, event, status, term, body)"
            " VALUES (%s, %s, %s, %s, %s, %s)",
            (task.id, task.updated_at, event, task.status.value, term, body),
        )
        db.execute("SELECT pg_notify(%s, %s)", (TASKS_CHANNEL, task.id))

    def query(
        self, sql: str, args: tuple[Any, ...] | builtins.list[Any] = ()
    ) -> builtins.list[Any]:
        with self._connection() as db:
            return db.execute(sql, args).fetchall()

    # -- the TaskStore contract -------------------------------------------------------------
    def save(self, task: Task, event: str) -> None:
        self._write(lambda db, term: self._upsert(db, term, task, None, event))

    def save_new(self, task: Task, idempotency_key: str | None) -> Task:
        def insert(db: psycopg.Connection[Any], term: int) -> Task:
            if idempotency_key is not None:
                # Serialise writers of one key: the second waits, then finds the first's task.
                db.execute("SELECT pg_advisory_xact_lock(hashtext(%s))", (idempotency_key,))
                row = db.execute(
                    "SELECT body FROM tasks WHERE idempotency_key = %s", (idempotency_key,)
                ).fetchone()
                if row is not None:
                    return Task.model_validate_json(row[0])
            if db.execute("SELECT 1 FROM tasks WHERE id = %s", (task.id,)).fetchone():
                raise ValueError(f"task {task.id} already exists")
            self._upsert(db, term, task, idempotency_key, "created")
            return task.model_copy(deep=True)

        return self._write(insert)

    def save_state(self, key: str, value: str) -> None:
        self._write(
            lambda db, term: db.execute(
                "INSERT INTO service_state (key, value) VALUES (%s, %s)"
                " ON CONFLICT (key) DO UPDATE SET value=excluded.value",
                (key, value),
            )
        )

    def load_state(self, key: str) -> str | None:
        rows = self.query("SELECT value FROM service_state WHERE key = %s", (key,))
        return str(rows[0][0]) if rows else None

    def get(self, task_id: str) -> Task | None:
        rows = self.query("SELECT body FROM tasks WHERE id = %s", (task_id,))
        return Task.model_validate_json(rows[0][0]) if rows else None

    def list(
        self,
        status: TaskStatus | None = None,
        robot_id: str | None = None,
        *,
        after: TaskCursor | None = None,
        limit: int | None = None,
        newest_first: bool = False,
    ) -> builtins.list[Task]:
        """One indexed range scan (:func:`~fleet.service.store.list_query`)."""
        sql, args = list_query("%s", status, robot_id, after, limit, newest_first)
        return [Task.model_validate_json(r[0]) for r in self.query(sql, args)]

    def find_by_idempotency_key(self, key: str) -> Task | None:
        rows = self.query("SELECT body FROM tasks WHERE idempotency_key = %s", (key,))
        return Task.model_validate_json(rows[0][0]) if rows else None

    def unfinished(self) -> builtins.list[Task]:
        rows = self.query(
            "SELECT body FROM tasks WHERE status <> ALL(%s) ORDER BY created_at, id", (_FINAL,)
        )
        return [Task.model_validate_json(r[0]) for r in rows]

    def history(self, task_id: str) -> builtins.list[tuple[float, str, Task]]:
        rows = self.query(
            "SELECT at, event, body FROM task_history WHERE task_id = %s ORDER BY seq",
            (task_id,),
        )
        return [(float(r[0]), str(r[1]), Task.model_validate_json(r[2])) for r in rows]

    def delete_finished_before(self, before: float, limit: int = 1000) -> int:
        def purge(db: psycopg.Connection[Any], term: int) -> int:
            ids = [
                str(r[0])
                for r in db.execute(
                    "DELETE FROM tasks WHERE id IN (SELECT id FROM tasks WHERE status = ANY(%s)"
                    " AND updated_at < %s LIMIT %s) RETURNING id",
                    (_FINAL, before, limit),
                ).fetchall()
            ]
            if ids:
                db.execute("DELETE FROM task_history WHERE task_id = ANY(%s)", (ids,))
            return len(ids)

        return self._write(purge)

    def close(self) -> None:
        """Close every pooled connection; idempotent (calls in flight finish first)."""
        if self._closed:
            return
        self._closed = True
        while True:
            try:
                conn = self._pool.get_nowait()
            except queue.Empty:
                return
            if conn is not None:
                conn.close()
