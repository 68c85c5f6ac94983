"""TaskStore contract on a real SQLite file, a real PostgreSQL server (and the in-memory
twin)."""

from __future__ import annotations

import socket
import sqlite3
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import psycopg
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fleet.core.tasks import Task, TaskRequest, TaskStatus
from fleet.core.wire import Pose
from fleet.service.store import MemoryTaskStore, SqliteTaskStore, TaskStore
from fleet.service.store_postgres import PostgresTaskStore, StoreUnavailable


def _task(task_id: str, t: float = 1.0, robot: str | None = None) -> Task:
    request = TaskRequest(goal=Pose(x=1.0, y=2.0, theta=0.5), robot_id=robot)
    return Task(id=task_id, request=request, created_at=t, updated_at=t)


@pytest.fixture(params=["sqlite", "postgres", "memory"])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[TaskStore]:
    s: TaskStore
    if request.param == "sqlite":
        s = SqliteTaskStore(tmp_path / "nested" / "tasks.db")
    elif request.param == "postgres":
        s = PostgresTaskStore(request.getfixturevalue("postgres_dsn"))
    else:
        s = MemoryTaskStore()
    yield s
    s.close()


def test_save_get_list_and_history(store: TaskStore) -> None:
    a = store.save_new(_task("a", 1.0, "r1"), None)
    store.save_new(_task("b", 2.0), None)
    assert store.get("a") == a
    assert store.get("missing") is None
    driving = a.model_copy(update={"status": TaskStatus.DRIVING, "updated_at": 3.0})
    store.save(driving, "acknowledged")
    assert store.get("a") == driving
    assert [t.id for t in store.list()] == ["a", "b"]
    assert [t.id for t in store.list(status=TaskStatus.DRIVING)] == ["a"]
    assert [t.id for t in store.list(robot_id="r1")] == ["a"]
    assert [t.id for t in store.unfinished()] == ["a", "b"]
    events = [(ev, t.status) for _, ev, t in store.history("a")]
    assert events == [("created", TaskStatus.QUEUED), ("acknowledged", TaskStatus.DRIVING)]


def test_service_state_documents_are_replaced_by_key(store: TaskStore) -> None:
    assert store.load_state("operator") is None
    store.save_state("operator", '{"v": 1}')
    store.save_state("other", "[]")
    store.save_state("operator", '{"v": 2}')
    assert (store.load_state("operator"), store.load_state("other")) == ('{"v": 2}', "[]")


def test_idempotency_key_returns_the_first_task(store: TaskStore) -> None:
    first = store.save_new(_task("a"), "key-1")
    again = store.save_new(_task("b"), "key-1")
    assert again.id == first.id == "a"
    assert store.get("b") is None
    assert store.find_by_idempotency_key("key-1") == first
    assert store.find_by_idempotency_key("key-2") is None


def test_finished_tasks_are_not_unfinished(store: TaskStore) -> None:
    a = store.save_new(_task("a"), None)
    store.save(a.model_copy(update={"status": TaskStatus.SUCCEEDED}), "succeeded")
    assert store.unfinished() == []


def test_finished_tasks_older_than_the_cutoff_are_deleted_with_their_history(
    store: TaskStore,
) -> None:
    for name, t, status in [
        ("old-done", 1.0, TaskStatus.SUCCEEDED),
        ("old-failed", 2.0, TaskStatus.FAILED),
        ("old-open", 3.0, TaskStatus.DRIVING),
        ("new-done", 20.0, TaskStatus.CANCELLED),
    ]:
        task = store.save_new(_task(name, t), f"key-{name}")
        store.save(task.model_copy(update={"status": status, "updated_at": t}), status.value)
    assert store.delete_finished_before(10.0, limit=1) == 1  # bounded per call
    assert store.delete_finished_before(10.0) == 1
    assert store.delete_finished_before(10.0) == 0
    assert sorted(t.id for t in store.list()) == ["new-done", "old-open"]
    assert store.history("old-done") == [] and store.history("old-failed") == []
    assert len(store.history("old-open")) == 2
    assert store.find_by_idempotency_key("key-old-done") is None
    # The key of a purged task may be used again (it is a new task then).
    again = store.save_new(_task("again", 30.0), "key-old-done")
    assert again.id == "again"


def test_concurrent_save_new_with_one_key_creates_one_task(store: TaskStore) -> None:
    results: list[str] = []
    lock = threading.Lock()

    def worker(i: int) -> None:
        got = store.save_new(_task(f"t{i}"), "same")
        with lock:
            results.append(got.id)

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(16)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(set(results)) == 1
    assert len(store.list()) == 1


def test_sqlite_survives_reopen_and_uses_wal(tmp_path: Path) -> None:
    path = tmp_path / "data" / "tasks.db"
    store = SqliteTaskStore(path)
    a = store.save_new(_task("a"), "k")
    store.save(a.model_copy(update={"status": TaskStatus.ASSIGNED, "robot_id": "r1"}), "assigned")
    store.close()
    store.close()  # idempotent

    reopened = SqliteTaskStore(path)
    try:
        got = reopened.get("a")
        assert got is not None and got.status == TaskStatus.ASSIGNED and got.robot_id == "r1"
        assert reopened.find_by_idempotency_key("k") == got
        assert [t.id for t in reopened.unfinished()] == ["a"]
        assert len(reopened.history("a")) == 2
    finally:
        reopened.close()
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    db.close()


def test_closed_store_raises(tmp_path: Path) -> None:
    store = SqliteTaskStore(tmp_path / "x.db")
    store.close()
    with pytest.raises(RuntimeError, match="closed"):
        store.get("a")


def test_concurrent_saves_share_commits_and_all_land(tmp_path: Path) -> None:
    """Group commit: concurrent writers each return only after their write is committed;
    a failing write (duplicate id) fails alone; every other write is on disk."""
    store = SqliteTaskStore(tmp_path / "tasks.db")
    errors: list[BaseException] = []
    barrier = threading.Barrier(8)

    def writer(w: int) -> None:
        barrier.wait()
        for k in range(25):
            try:
                store.save_new(_task(f"w{w}-{k}", t=float(k)), f"key-{w}-{k}")
                if k == 0:
                    store.save_new(_task(f"w{w}-{k}"), None)  # duplicate id: must fail alone
            except ValueError as e:
                errors.append(e)

    threads = [threading.Thread(target=writer, args=(w,)) for w in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(errors) == 8 and all("already exists" in str(e) for e in errors)
    assert store.writes == 8 * 26 and 1 <= store.commits <= store.writes
    store.close()
    reopened = SqliteTaskStore(tmp_path / "tasks.db")  # a new connection sees every write
    assert len(reopened.list()) == 8 * 25
    assert reopened.find_by_idempotency_key("key-7-24") is not None
    reopened.close()


def test_same_idempotency_key_in_one_group_yields_one_task(tmp_path: Path) -> None:
    store = SqliteTaskStore(tmp_path / "tasks.db")
    barrier = threading.Barrier(6)
    results: list[Task] = []

    def writer(w: int) -> None:
        barrier.wait()
        results.append(store.save_new(_task(f"t{w}"), "same-key"))

    threads = [threading.Thread(target=writer, args=(w,)) for w in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len({r.id for r in results}) == 1
    assert len(store.list()) == 1
    store.close()


# -- pages of the task list ------------------------------------------------------------------
_listed = st.lists(
    st.tuples(
        st.sampled_from([1.0, 2.0, 3.0]),  # few creation times: ties are the hard case
        st.sampled_from(list(TaskStatus)),
        st.sampled_from([None, "r1", "r2"]),
    ),
    max_size=12,
)


@settings(max_examples=40, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    rows=_listed,
    page=st.integers(1, 5),
    newest_first=st.booleans(),
    status=st.sampled_from([None, TaskStatus.QUEUED, TaskStatus.SUCCEEDED]),
    robot=st.sampled_from([None, "r1"]),
)
def test_pages_walk_the_filtered_list_in_order_once_each(
    postgres_dsn: str,
    rows: list[tuple[float, TaskStatus, str | None]],
    page: int,
    newest_first: bool,
    status: TaskStatus | None,
    robot: str | None,
) -> None:
    """Following the cursor page by page yields every matching task once, in
    ``(created_at, id)`` order (reversed for newest first); SQLite, PostgreSQL (one database,
    emptied for each example) and memory agree."""
    with tempfile.TemporaryDirectory() as tmp:
        postgres = PostgresTaskStore(postgres_dsn)
        with psycopg.connect(postgres_dsn, autocommit=True) as db:  # a fresh start per example
            db.execute("TRUNCATE tasks, task_history")
        stores: list[TaskStore] = [SqliteTaskStore(Path(tmp) / "t.db"), MemoryTaskStore(), postgres]
        try:
            for k, (t, task_status, rid) in enumerate(rows):
                task = _task(f"id{(k * 7) % 13:02d}-{k}", t, rid)
                for store in stores:
                    store.save_new(task.model_copy(update={"status": task_status}), None)
            walks = []
            for store in stores:
                walked: list[str] = []
                cursor = None
                while True:
                    got = store.list(
                        status, robot, after=cursor, limit=page, newest_first=newest_first
                    )
                    assert len(got) <= page
                    walked += [t.id for t in got]
                    if len(got) < page:
                        break
                    cursor = (got[-1].created_at, got[-1].id)
                walks.append(walked)
            everything = sorted(stores[1].list(status, robot), key=lambda t: (t.created_at, t.id))
            expected = [t.id for t in everything][:: -1 if newest_first else 1]
            assert walks == [expected, expected, expected]
            assert [t.id for t in stores[0].list(status, robot)] == [t.id for t in everything]
        finally:
            for store in stores:
                store.close()


def _vm_steps(store: SqliteTaskStore, **page: object) -> int:
    """SQLite VM instructions (in tens) spent listing one page."""
    steps = 0

    def count() -> int:
        nonlocal steps
        steps += 1
        return 0

    store._conn.set_progress_handler(count, 10)
    try:
        assert len(store.list(**page)) == 10  # type: ignore[arg-type]
    finally:
        store._conn.set_progress_handler(None, 10)
    return steps


@pytest.mark.parametrize("status", [None, TaskStatus.SUCCEEDED])
def test_a_page_costs_the_same_however_many_tasks_are_stored(
    tmp_path: Path, status: TaskStatus | None
) -> None:
    """Paging happens in SQL on an index: neither loading every row nor sorting them."""
    store = SqliteTaskStore(tmp_path / "tasks.db")
    try:
        costs = []
        for total in (200, 6000):
            with sqlite3.connect(tmp_path / "tasks.db") as db:  # bulk insert, one commit
                db.execute("DELETE FROM tasks")
                db.executemany(
                    "INSERT INTO tasks (id, status, robot_id, created_at, updated_at, body)"
                    " VALUES (?, ?, NULL, ?, ?, ?)",
                    [
                        (t.id, t.status.value, t.created_at, t.created_at, t.model_dump_json())
                        for t in (
                            _task(f"t{k:05d}", float(k)).model_copy(
                                update={"status": TaskStatus.SUCCEEDED}
                            )
                            for k in range(total)
                        )
                    ],
                )
            db.close()
            middle = (total / 2, f"t{total // 2:05d}")
            costs.append(
                [
                    _vm_steps(store, status=status, after=middle, limit=10, newest_first=newest)
                    for newest in (False, True)
                ]
            )
        # 30x the rows: the same work per page, give or take a level of the b-tree
        # (a scan or a sort of every row would cost hundreds of times more)
        assert all(big <= 2 * small for small, big in zip(*costs, strict=True)), costs
    finally:
        store.close()


def test_postgres_is_shared_a_second_store_sees_every_write(postgres_dsn: str) -> None:
    """Two stores on one database (a leader and a standby) see the same tasks and history."""
    first, second = PostgresTaskStore(postgres_dsn), PostgresTaskStore(postgres_dsn)
    try:
        a = first.save_new(_task("a"), "k")
        first.save(a.model_copy(update={"status": TaskStatus.ASSIGNED, "robot_id": "r1"}), "x")
        got = second.get("a")
        assert got is not None and got.status == TaskStatus.ASSIGNED and got.robot_id == "r1"
        assert second.find_by_idempotency_key("k") == got
        assert [t.id for t in second.unfinished()] == ["a"] and len(second.history("a")) == 2
        assert second.save_new(_task("b"), "k").id == "a"  # the key is the database's
    finally:
        first.close()
        second.close()
    first.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        first.get("a")


def test_postgres_unreachable_at_open_says_where_without_the_password() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nobody listens here once closed
    with pytest.raises(
        StoreUnavailable, match=rf"unreachable at postgresql://127.0.0.1:{port}/"
    ) as e:
        PostgresTaskStore(f"postgresql://u:secret@127.0.0.1:{port}/db", timeout_s=1.0)
    assert "secret" not in str(e.value)
