"""``open_fleet``: the one assembly of a running fleet (router, store, bus, service, trimmer)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet.core.tasks import TaskRequest, TaskStatus
from fleet.core.wire import Pose
from fleet.io.settings import Settings, load_settings
from fleet.io.transport import open_session
from fleet.service.host import open_fleet
from fleet.service.store import MemoryTaskStore, SqliteTaskStore, TaskStore

pytestmark = pytest.mark.integration


def _settings(tmp_path: Path) -> Settings:
    return load_settings(listen=["tcp/127.0.0.1:0"], data_dir=tmp_path / "var")


def test_opens_a_router_and_a_sqlite_store_in_the_data_dir_and_serves_tasks(
    tmp_path: Path,
) -> None:
    settings = _settings(tmp_path)
    with open_fleet(settings) as fleet:
        assert fleet.locators and fleet.locators[0].startswith("tcp/127.0.0.1:")
        assert not fleet.locators[0].endswith(":0")  # the real port
        task = fleet.service.submit(TaskRequest(goal=Pose(x=3.0, y=2.0)))
        assert fleet.store.get(task.id) is not None
    assert settings.db_path == tmp_path / "var" / "parkfleet.db"
    reopened = SqliteTaskStore(settings.db_path)
    try:
        stored = reopened.get(task.id)
        assert stored is not None and stored.status is TaskStatus.QUEUED
    finally:
        reopened.close()


class _ClosedStore(MemoryTaskStore):
    closed = False

    def close(self) -> None:
        self.closed = True
        super().close()


def test_the_store_is_one_parameter_closed_with_the_fleet_on_a_given_session(
    tmp_path: Path,
) -> None:
    settings = _settings(tmp_path)
    made: list[_ClosedStore] = []

    def store(given: Settings) -> TaskStore:
        assert given is settings
        made.append(_ClosedStore())
        return made[0]

    with open_session(settings, "router") as session:  # e.g. one router for many runs
        with open_fleet(settings, store=store, session=session) as fleet:
            assert fleet.store is made[0] and fleet.locators == []  # the owner knows them
            fleet.service.submit(TaskRequest(goal=Pose(x=-3.0, y=1.0)))
            assert len(made[0].list()) == 1
        assert made[0].closed
        assert not session.is_closed()  # a given session stays its owner's
    assert not (tmp_path / "var").exists()  # no SQLite file was made
