"""Shared fixtures: a real Zenoh router on a free loopback port; a real PostgreSQL server."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator

import pytest
from hypothesis import settings as hypothesis_settings

from fleet.io.settings import Settings, load_settings
from fleet.io.transport import listening_locators, open_session, tcp_endpoint

# Machines are shared and noisy: a per-example deadline would make timing decide a test.
hypothesis_settings.register_profile("parkfleet", deadline=None, print_blob=True)
hypothesis_settings.load_profile("parkfleet")


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the control step once (numba's on-disk cache) before any test starts a
    ``parkfleet`` child: on a fresh clone every child would otherwise compile it for
    itself, and under load that takes longer than the children's start-up waits."""
    from fleet.core.params import Gains
    from fleet.core.simulate import BatchProblem, simulate

    simulate(
        BatchProblem.build((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), Gains(kx=1, ky=1, ktheta=1), "cw")
    )


@pytest.fixture
def router_endpoint() -> Iterator[str]:
    """A Zenoh router listening on ``tcp/127.0.0.1:<free port>``; yields its endpoint."""
    settings = load_settings(listen=["tcp/127.0.0.1:0"])
    with open_session(settings, "router") as session:
        yield tcp_endpoint(listening_locators(session))


@pytest.fixture
def client_settings(router_endpoint: str) -> Settings:
    """Settings of a client session connected to the test router."""
    return load_settings(connect=[router_endpoint])


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[str]:
    """The URL of a real PostgreSQL server for the whole run: ``PARKFLEET_TEST_POSTGRES``
    (``postgresql://user@host:port/db``) if set, else a throwaway cluster
    (:class:`fleet.io.postgres_cluster.TempCluster`, torn down at the end). Without
    PostgreSQL the tests skip locally and fail under CI (``CI=true``)."""
    given = os.environ.get("PARKFLEET_TEST_POSTGRES")
    if given:
        yield given
        return
    from fleet.io.postgres_cluster import TempCluster, find_bindir

    found = find_bindir()
    if isinstance(found, str):
        if os.environ.get("CI") == "true":
            pytest.fail(f"PostgreSQL tests cannot run in CI: {found}")
        pytest.skip(found)
    with TempCluster(found) as cluster:
        yield cluster.dsn


@pytest.fixture
def postgres_dsn(postgres_server: str) -> Iterator[str]:
    """A fresh, empty database on the test server for one test (dropped after it)."""
    import psycopg
    from psycopg import sql

    name = f"t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(postgres_server, autocommit=True) as admin:
        admin.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
    base, _, _ = postgres_server.rpartition("/")  # a URL, as users give --store
    yield f"{base}/{name}"
    with psycopg.connect(postgres_server, autocommit=True) as admin:
        admin.execute(sql.SQL("DROP DATABASE {} WITH (FORCE)").format(sql.Identifier(name)))
