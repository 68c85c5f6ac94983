"""Task persistence: every transition is stored (durably) before the service announces it.

Two implementations of :class:`TaskStore`:

* :class:`SqliteTaskStore` -- one SQLite file in WAL mode with ``synchronous=FULL``, so a
  ``save`` has reached the disk when it returns (durable against a process crash *and* a
  power loss); a ``tasks`` table (latest version of each task, unique idempotency key) and
  an append-only ``task_history`` table (one row per transition, with its event name),
  and a small ``service_state`` table (named JSON documents the service keeps across
  restarts: what operators asked, robots out of service).
  Writes use **group commit**: concurrent ``save``/``save_new`` calls are queued, and one
  caller (the leader) runs every queued write in one transaction -- each in its own
  savepoint, so one failing write does not undo the others -- and commits once, i.e. one
  fsync for the whole group; every caller returns (or raises) only after that commit. A
  lone writer pays one fsync as before; under load the fsync cost is shared. (WAL with
  ``synchronous=NORMAL`` would skip the fsync entirely and still survive a killed process,
  but not a power loss; group commit keeps the stronger guarantee at a similar rate.)
* :class:`MemoryTaskStore` -- the same contract in memory, for unit tests.

Both are thread-safe (one lock each): the API, the tick thread and Zenoh callbacks share them.
"""

from __future__ import annotations

import builtins
import sqlite3
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

from fleet.core.tasks import Task, TaskStatus

_FINAL = tuple(s.value for s in TaskStatus if s.final)

_SCHEMA = """
CREATE TABLE IF NOT EXISTS tasks (
    id TEXT PRIMARY KEY,
    status TEXT NOT NULL,
    robot_id TEXT,
    idempotency_key TEXT UNIQUE,
    created_at REAL NOT NULL,
    updated_at REAL NOT NULL,
    body TEXT NOT NULL
);
-- Pages of the task list (``list``) walk one of these in (created_at, id) order from a
-- cursor, so a page costs the same however many tasks are stored. They cover the
-- single-column indexes of earlier versions, which are dropped.
DROP INDEX IF EXISTS tasks_status;
DROP INDEX IF EXISTS tasks_robot;
DROP INDEX IF EXISTS tasks_created;
CREATE INDEX IF NOT EXISTS tasks_page ON tasks (created_at, id);
CREATE INDEX IF NOT EXISTS tasks_status_page ON tasks (status, created_at, id);
CREATE INDEX IF NOT EXISTS tasks_robot_page ON tasks (robot_id, created_at, id);
CREATE TABLE IF NOT EXISTS task_history (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    task_id TEXT NOT NULL,
    at REAL NOT NULL,
    event TEXT NOT NULL,
    status TEXT NOT NULL,
    body TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS task_history_task ON task_history (task_id);
CREATE TABLE IF NOT EXISTS service_state (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
"""


_T = TypeVar("_T")

TaskCursor = tuple[float, str]
"""A position in the task list: ``(created_at, id)`` of the last task of the previous page.
Tasks are listed in ``(created_at, id)`` order (reversed for newest first)."""


def _page_key(task: Task) -> TaskCursor:
    return (task.created_at, task.id)


class _Write(Generic[_T]):
    """One queued write of a group commit: its operation and, once committed, its outcome."""

    __slots__ = ("done", "error", "op", "result")

    def __init__(self, op: Callable[[sqlite3.Connection], _T]) -> None:
        self.op = op
        self.done = False
        self.result: _T | None = None
        self.error: BaseException | None = None


def robot_of(task: Task) -> str | None:
    """The robot a task belongs to: its assigned robot, else the one its request names."""
    return task.robot_id or task.request.robot_id


def list_query(
    mark: str,
    status: TaskStatus | None,
    robot_id: str | None,
    after: TaskCursor | None,
    limit: int | None,
    newest_first: bool,
) -> tuple[str, list[str | float | int]]:
    """The SQL (and its arguments) of :meth:`TaskStore.list` for a database whose
    parameter mark is ``mark`` (``?`` SQLite, ``%s`` PostgreSQL): one indexed range scan
    (``tasks_*page``), so a page costs the same at any depth."""
    sql = "SELECT body FROM tasks"
    where: list[str] = []
    args: list[str | float | int] = []
    if status is not None:
        where.append(f"status = {mark}")
        args.append(TaskStatus(status).value)
    if robot_id is not None:
        where.append(f"robot_id = {mark}")
        args.append(robot_id)
    if after is not None:
        where.append(f"(created_at, id) {'<' if newest_first else '>'} ({mark}, {mark})")
        args += [float(after[0]), str(after[1])]
    if where:
        sql += " WHERE " + " AND ".join(where)
    sql += " ORDER BY created_at DESC, id DESC" if newest_first else " ORDER BY created_at, id"
    if limit is not None:
        sql += f" LIMIT {mark}"
        args.append(int(limit))
    return sql, args


class TaskStore(Protocol):
    """Persistence of tasks and their history."""

    def save(self, task: Task, event: str) -> None:
        """Upsert ``task`` and append ``(task, event)`` to its history; durable on return."""
        ...

    def get(self, task_id: str) -> Task | None: ...

    def list(
        self,
        status: TaskStatus | None = None,
        robot_id: str | None = None,
        *,
        after: TaskCursor | None = None,
        limit: int | None = None,
        newest_first: bool = False,
    ) -> builtins.list[Task]:
        """Tasks in creation order ``(created_at, id)``, oldest first (or ``newest_first``),
        optionally filtered by status and by robot (the robot the task is assigned to, or
        else the robot the request names). A page: at most ``limit`` tasks, those that come
        after the cursor ``after`` in that order."""
        ...

    def find_by_idempotency_key(self, key: str) -> Task | None: ...

    def save_new(self, task: Task, idempotency_key: str | None) -> Task:
        """Insert a new task atomically; if ``idempotency_key`` is taken return that task."""
        ...

    def unfinished(self) -> builtins.list[Task]:
        """Tasks not in a final state (queued, assigned, driving), in creation order."""
        ...

    def history(self, task_id: str) -> builtins.list[tuple[float, str, Task]]:
        """(updated_at, event, task) of every stored transition of one task, oldest first."""
        ...

    def delete_finished_before(self, before: float, limit: int = 1000) -> int:
        """Delete up to ``limit`` finished tasks (succeeded, failed, cancelled) last updated
        before ``before`` [s since epoch], with their history; returns how many went."""
        ...

    def save_state(self, key: str, value: str) -> None:
        """Replace the service's state document ``key``; durable on return."""
        ...

    def load_state(self, key: str) -> str | None:
        """The state document ``key`` last saved (None: never)."""
        ...

    def close(self) -> None: ...


class MemoryTaskStore:
    """In-memory :class:`TaskStore` for unit tests (copies in and out, like a database)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._tasks: dict[str, Task] = {}
        self._keys: dict[str, str] = {}
        self._history: builtins.list[tuple[float, str, Task]] = []
        self._state: dict[str, str] = {}

    def save_state(self, key: str, value: str) -> None:
        with self._lock:
            self._state[key] = value

    def load_state(self, key: str) -> str | None:
        with self._lock:
            return self._state.get(key)

    def save(self, task: Task, event: str) -> None:
        with self._lock:
            self._tasks[task.id] = task.model_copy(deep=True)
            self._history.append((task.updated_at, event, task.model_copy(deep=True)))

    def get(self, task_id: str) -> Task | None:
        with self._lock:
            task = self._tasks.get(task_id)
            return None if task is None else task.model_copy(deep=True)

    def list(
        self,
        status: TaskStatus | None = None,
        robot_id: str | None = None,
        *,
        after: TaskCursor | None = None,
        limit: int | None = None,
        newest_first: bool = False,
    ) -> builtins.list[Task]:
        with self._lock:
            ordered = sorted(self._tasks.values(), key=_page_key, reverse=newest_first)
            page = [
                t.model_copy(deep=True)
                for t in ordered
                if (status is None or t.status == status)
                and (robot_id is None or robot_of(t) == robot_id)
                and (
                    after is None
                    or (_page_key(t) < after if newest_first else _page_key(t) > after)
                )
            ]
        return page if limit is None else page[:limit]

    def find_by_idempotency_key(self, key: str) -> Task | None:
        with self._lock:
            task_id = self._keys.get(key)
        return None if task_id is None else self.get(task_id)

    def save_new(self, task: Task, idempotency_key: str | None) -> Task:
        with self._lock:
            if idempotency_key is not None and idempotency_key in self._keys:
                return self._tasks[self._keys[idempotency_key]].model_copy(deep=True)
            if task.id in self._tasks:
                raise ValueError(f"task {task.id} already exists")
            if idempotency_key is not None:
                self._keys[idempotency_key] = task.id
            self._tasks[task.id] = task.model_copy(deep=True)
            self._history.append((task.updated_at, "created", task.model_copy(deep=True)))
            return task.model_copy(deep=True)

    def unfinished(self) -> builtins.list[Task]:
        return [t for t in self.list() if not t.status.final]

    def history(self, task_id: str) -> builtins.list[tuple[float, str, Task]]:
        with self._lock:
            return [
                (at, ev, t.model_copy(deep=True)) for at, ev, t in self._history if t.id == task_id
            ]

    def delete_finished_before(self, before: float, limit: int = 1000) -> int:
        with self._lock:
            gone = [t.id for t in self._tasks.values() if t.status.final and t.updated_at < before][
                :limit
            ]
            for task_id in gone:
                del self._tasks[task_id]
            dropped = set(gone)
            self._keys = {k: v for k, v in self._keys.items() if v not in dropped}
            self._history = [h for h in self._history if h[2].id not in dropped]
            return len(gone)

    def close(self) -> None:
        pass


class SqliteTaskStore:
    """SQLite :class:`TaskStore` (WAL, ``synchronous=FULL``, group commit): a save is on
    disk on return (see the module docstring)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()  # the connection
        self._queue_cv = threading.Condition()  # the write queue and the leader flag
        self._queue: builtins.list[_Write[Any]] = []
        self._leader = False
        #: Commits and writes so far (writes / commits = mean group size).
        self.commits = 0
        self.writes = 0
        self._db: sqlite3.Connection | None = sqlite3.connect(
            str(self.path), check_same_thread=False, isolation_level=None, timeout=30.0
        )
        db = self._db
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        db.execute("PRAGMA foreign_keys=ON")
        db.executescript(_SCHEMA)

    @property
    def _conn(self) -> sqlite3.Connection:
        if self._db is None:
            raise RuntimeError("task store is closed")
        return self._db

    def _upsert(self, db: sqlite3.Connection, task: Task, key: str | None, event: str) -> None:
        body = task.model_dump_json()
        db.execute(
            "INSERT INTO tasks (id, status, robot_id, idempotency_key, created_at, updated_at,"
            " body) VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT(id) DO UPDATE SET"
            " status=excluded.status, robot_id=excluded.robot_id,"
            " updated_at=excluded.updated_at, body=excluded.body",
            (
                task.id,
                task.status.value,
                robot_of(task),
                key,
                task.created_at,
                task.updated_at,
                body,
            ),
        )
        db.execute(
            "INSERT INTO task_history (task_id, at, event, status, body) VALUES (?, ?, ?, ?, ?)",
            (task.id, task.updated_at, event, task.status.value, body),
        )

    def _write(self, op: Callable[[sqlite3.Connection], _T]) -> _T:
        """Run ``op`` in a committed transaction (group commit, see the module docstring)."""
        mine: _Write[_T] = _Write(op)
        with self._queue_cv:
            self._queue.append(mine)
            while self._leader and not mine.done:
                self._queue_cv.wait()
            lead = not mine.done  # nobody took it: lead the next group (it holds ``mine``)
            if lead:
                self._leader = True
                batch, self._queue = self._queue, []
        if lead:
            try:
                self._commit(batch)
            finally:
                with self._queue_cv:
                    self._leader = False
                    self._queue_cv.notify_all()
        if mine.error is not None:
            raise mine.error
        return mine.result  # type: ignore[return-value]

    def _commit(self, batch: builtins.list[_Write[Any]]) -> None:
        """Run a group of writes in one transaction, each in a savepoint; commit once."""
        try:
            with self._lock:
                db = self._conn
                db.execute("BEGIN IMMEDIATE")
                try:
                    for w in batch:
                        db.execute("SAVEPOINT w")
                        try:
                            w.result = w.op(db)
                        except Exception as e:
                            db.execute("ROLLBACK TO w")
                            w.error = e
                        db.execute("RELEASE w")
                    db.execute("COMMIT")
                except BaseException:
                    if db.in_transaction:
                        db.execute("ROLLBACK")
                    raise
                self.commits += 1
                self.writes += len(batch)
        except BaseException as e:
            for w in batch:
                w.error, w.result = e, None
            raise
        finally:
            for w in batch:
                w.done = True

    def save(self, task: Task, event: str) -> None:
        self._write(lambda db: self._upsert(db, task, None, event))

    def save_state(self, key: str, value: str) -> None:
        self._write(
            lambda db: db.execute(
                "INSERT INTO service_state (key, value) VALUES (?, ?)"
                " ON CONFLICT(key) DO UPDATE SET value=excluded.value",
                (key, value),
            )
        )

    def load_state(self, key: str) -> str | None:
        with self._lock:
            row = self._conn.execute(
                "SELECT value FROM service_state WHERE key = ?", (key,)
            ).fetchone()
        return None if row is None else str(row[0])

    def get(self, task_id: str) -> Task | None:
        with self._lock:
            row = self._conn.execute("SELECT body FROM tasks WHERE id = ?", (task_id,)).fetchone()
        return None if row is None else Task.model_validate_json(row[0])

    def list(
        self,
        status: TaskStatus | None = None,
        robot_id: str | None = None,
        *,
        after: TaskCursor | None = None,
        limit: int | None = None,
        newest_first: bool = False,
    ) -> builtins.list[Task]:
        """One indexed range scan (:func:`list_query`)."""
        sql, args = list_query("?", status, robot_id, after, limit, newest_first)
        with self._lock:
            rows = self._conn.execute(sql, args).fetchall()
        return [Task.model_validate_json(r[0]) for r in rows]

    def find_by_idempotency_key(self, key: str) -> Task | None:
        with self._lock:
            row = self._conn.execute(
                "SELECT body FROM tasks WHERE idempotency_key = ?", (key,)
            ).fetchone()
        return None if row is None else Task.model_validate_json(row[0])

    def save_new(self, task: Task, idempotency_key: str | None) -> Task:
        def insert(db: sqlite3.Connection) -> Task:
            if idempotency_key is not None:
                row = db.execute(
                    "SELECT body FROM tasks WHERE idempotency_key = ?", (idempotency_key,)
                ).fetchone()
                if row is not None:
                    return Task.model_validate_json(row[0])
            if db.execute("SELECT 1 FROM tasks WHERE id = ?", (task.id,)).fetchone():
                raise ValueError(f"task {task.id} already exists")
            self._upsert(db, task, idempotency_key, "created")
            return task  # as written (no copy: a transition makes a new Task, none is changed)

        return self._write(insert)

    def unfinished(self) -> builtins.list[Task]:
        marks = ", ".join("?" for _ in _FINAL)
        with self._lock:
            rows = self._conn.execute(
                f"SELECT body FROM tasks WHERE status NOT IN ({marks}) ORDER BY created_at, rowid",
                _FINAL,
            ).fetchall()
        return [Task.model_validate_json(r[0]) for r in rows]

    def history(self, task_id: str) -> builtins.list[tuple[float, str, Task]]:
        with self._lock:
            rows = self._conn.execute(
                "SELECT at, event, body FROM task_history WHERE task_id = ? ORDER BY seq",
                (task_id,),
            ).fetchall()
        return [(float(r[0]), str(r[1]), Task.model_validate_json(r[2])) for r in rows]

    def delete_finished_before(self, before: float, limit: int = 1000) -> int:
        """Retention of finished tasks (one bounded transaction; see :class:`TaskStore`)."""
        marks = ", ".join("?" for _ in _FINAL)

        def purge(db: sqlite3.Connection) -> int:
            # Finds old finished rows without scanning every task (a no-op once it exists).
            db.execute("CREATE INDEX IF NOT EXISTS tasks_finished ON tasks (status, updated_at)")
            ids = [
                str(r[0])
                for r in db.execute(
                    f"SELECT id FROM tasks WHERE status IN ({marks}) AND updated_at < ? LIMIT ?",
                    (*_FINAL, before, limit),
                )
            ]
            if ids:
                qs = ", ".join("?" for _ in ids)
                db.execute(f"DELETE FROM task_history WHERE task_id IN ({qs})", ids)
                db.execute(f"DELETE FROM tasks WHERE id IN ({qs})", ids)
            return len(ids)

        return self._write(purge)

    def close(self) -> None:
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None
