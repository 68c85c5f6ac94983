"""Which task store a location names: ``postgresql://`` (or ``postgres://``) URLs open
:class:`~fleet.service.store_postgres.PostgresTaskStore`, anything else is a SQLite file;
unset is SQLite at ``<data_dir>/parkfleet.db`` (the embedded default)."""

from __future__ import annotations

from pathlib import Path

from fleet.io.settings import Settings
from fleet.service.store import SqliteTaskStore, TaskStore

_POSTGRES = ("postgresql://", "postgres://")


def is_postgres(location: str | None) -> bool:
    """Whether ``location`` is a PostgreSQL URL."""
    return location is not None and location.startswith(_POSTGRES)


def open_store(settings: Settings) -> TaskStore:
    """The store ``settings.store`` names (module docstring); PostgreSQL unreachable raises
    :class:`~fleet.service.store_postgres.StoreUnavailable` (a ``ConnectionError``)."""
    location = settings.store
    if is_postgres(location):
        from fleet.service.store_postgres import PostgresTaskStore

        assert location is not None
        return PostgresTaskStore(location)
    if location is None:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        return SqliteTaskStore(settings.db_path)
    return SqliteTaskStore(Path(location))


def check_store(settings: Settings) -> None:
    """Fail before serving if the PostgreSQL store is unreachable (a clear
    ``StoreUnavailable``, a ``ConnectionError``); nothing to check for SQLite."""
    if is_postgres(settings.store):
        from fleet.service.store_postgres import connect

        assert settings.store is not None
        connect(settings.store).close()
