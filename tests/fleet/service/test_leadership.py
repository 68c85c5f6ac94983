"""Leader election and fencing on a real PostgreSQL server (advisory lock, term, lease)."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator

import psycopg
import pytest
from support import wait_for

from fleet.core.tasks import Task, TaskRequest, TaskStatus
from fleet.core.wire import Pose
from fleet.io.postgres_cluster import TempCluster, find_bindir
from fleet.service.leadership import Leadership, read_leader
from fleet.service.roles import Role
from fleet.service.store_postgres import Deposed, PostgresTaskStore


def _task(task_id: str) -> Task:
    return Task(id=task_id, request=TaskRequest(goal=Pose(x=1.0, y=2.0)), created_at=1.0,
                updated_at=1.0)  # fmt: skip


class Candidate:
    """A store and a Leadership on it, recording what it was told."""

    def __init__(self, dsn: str, name: str, lease_s: float = 2.0) -> None:
        self.store = PostgresTaskStore(dsn)
        self.elected: list[int] = []
        self.deposed: list[str] = []
        self.lead = Leadership(
            self.store, name, f"http://{name}", lease_s=lease_s, poll_s=0.02,
            on_elected=self.elected.append, on_deposed=self.deposed.append,
        )  # fmt: skip

    def close(self) -> None:
        self.lead.close()
        self.store.close()


@pytest.fixture
def pair(postgres_dsn: str) -> Iterator[tuple[Candidate, Candidate]]:
    a, b = Candidate(postgres_dsn, "a"), Candidate(postgres_dsn, "b")
    try:
        yield a, b
    finally:
        a.close()
        b.close()


def _leader(a: Candidate, b: Candidate) -> tuple[Candidate, Candidate]:
    wait_for(lambda: Role.LEADER in (a.lead.role, b.lead.role), 30, "a leader")
    return (a, b) if a.lead.role is Role.LEADER else (b, a)


def test_one_leader_at_a_time_and_each_new_leader_raises_the_term(
    pair: tuple[Candidate, Candidate],
) -> None:
    a, b = pair
    a.lead.start()
    b.lead.start()
    first, second = _leader(a, b)
    assert first.elected == [1] and second.elected == [] and second.lead.role is Role.STANDBY
    first.store.save_new(_task("t1"), None)  # the leader writes under its term
    with pytest.raises(Deposed):
        second.store.save_new(_task("t2"), None)  # a standby writes nothing
    wait_for(lambda: second.lead.seen_leader == f"http://{first.lead.name}", 30, "leader seen")
    first.lead.close()  # steps down: the lock goes with its connection
    wait_for(lambda: second.lead.role is Role.LEADER, 30, "the standby taking over")
    assert second.elected == [2] and first.deposed == ["closed"]
    record = read_leader(second.store)
    assert (record.term, record.leader) == (2, second.lead.name)
    with pytest.raises(Deposed, match="term -1, the store's is 2"):
        first.store.save(_task("t1"), "late")
    second.store.save(_task("t1").model_copy(update={"status": TaskStatus.CANCELLED}), "x")
    stored = second.store.get("t1")
    assert stored is not None and stored.status is TaskStatus.CANCELLED


def test_a_write_racing_a_new_term_is_refused_inside_its_transaction(postgres_dsn: str) -> None:
    """The term check locks the leader row: a write of the old term waits for the new term's
    commit and then fails; nothing of it is stored."""
    store = PostgresTaskStore(postgres_dsn)
    try:
        store.fence(0)
        store.save_new(_task("a"), None)
        with psycopg.connect(postgres_dsn) as successor:  # a new leader, mid-transaction
            successor.execute("UPDATE parkfleet_leader SET term = term + 1 WHERE id = 1")
            outcome: list[BaseException | None] = []
            writer = threading.Thread(
                target=lambda: outcome.append(_catch(lambda: store.save_new(_task("b"), None)))
            )
            writer.start()
            wait_for(lambda: _waiting_on_lock(postgres_dsn), 30, "the write to wait for the row")
            successor.commit()
        writer.join()
        assert isinstance(outcome[0], Deposed)
        assert store.get("b") is None and [t.id for t in store.list()] == ["a"]
    finally:
        store.close()


def _catch(fn: object) -> BaseException | None:
    try:
        fn()  # type: ignore[operator]
    except BaseException as e:
        return e
    return None


def _waiting_on_lock(dsn: str) -> bool:
    with psycopg.connect(dsn) as db:
        row = db.execute(
            "SELECT count(*) FROM pg_stat_activity WHERE wait_event_type = 'Lock'"
            " AND datname = current_database()"
        ).fetchone()
    return row is not None and row[0] > 0


def test_a_leader_whose_session_is_killed_steps_down_and_the_standby_takes_over(
    pair: tuple[Candidate, Candidate], postgres_dsn: str
) -> None:
    a, b = pair
    a.lead.start()
    b.lead.start()
    first, second = _leader(a, b)
    with psycopg.connect(postgres_dsn, autocommit=True) as admin:
        admin.execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = %s",
            (f"parkfleet {first.lead.name}",),
        )
    wait_for(lambda: second.lead.role is Role.LEADER, 30, "the standby taking over")
    wait_for(lambda: first.deposed != [], 30, "the old leader stepping down")
    assert "lost PostgreSQL" in first.deposed[0] and second.elected == [2]
    with pytest.raises(Deposed):
        first.store.save_new(_task("x"), None)


def test_a_leader_that_loses_the_database_steps_down_and_leads_again_when_it_is_back() -> None:
    """A cluster of its own (its server is killed and restarted)."""
    found = find_bindir()
    if isinstance(found, str):
        if os.environ.get("CI") == "true":
            pytest.fail(f"PostgreSQL tests cannot run in CI: {found}")
        pytest.skip(found)
    with TempCluster(found) as cluster:
        c = Candidate(cluster.dsn, "solo", lease_s=1.0)
        try:
            c.lead.start()
            wait_for(lambda: c.lead.role is Role.LEADER, 30, "elected")
            cluster.kill_server()
            wait_for(lambda: c.lead.role is Role.STANDBY, 30, "stepping down")
            assert c.deposed and "lost PostgreSQL" in c.deposed[0]
            cluster.start_server()
            wait_for(lambda: c.elected == [1, 2], 20, f"elected again ({c.lead.last_error})")
        finally:
            c.close()
