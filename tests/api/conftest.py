"""API tests: the real app (routes, validation, auth, errors) over ASGI, with the real
fleet service and a real SQLite store; only the Zenoh bus is the in-memory one."""

from __future__ import annotations

import time
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import httpx
import pytest
from pydantic import SecretStr

from api.app import create_app
from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.io.settings import Settings, load_settings
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore

TOKEN = "s3cret-token"


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def settings() -> Settings:
    return load_settings(yard=(-10.0, 10.0, -5.0, 5.0))


@pytest.fixture
def bus() -> MemoryBus:
    return MemoryBus()


@pytest.fixture
def fleet(settings: Settings, bus: MemoryBus, tmp_path: Path) -> Iterator[FleetService]:
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    try:
        with FleetService(settings, bus, store) as service:
            yield service
    finally:
        store.close()


def add_robot(bus: MemoryBus, robot_id: str, x: float = 0.0, y: float = 0.0) -> None:
    """A robot appears: liveliness token, then an idle state."""
    bus.robot_alive(robot_id)
    bus.deliver_state(
        RobotState(
            robot_id=robot_id, seq=0, stamp=time.time(), pose=Pose(x=x, y=y), mode=RobotMode.IDLE
        )
    )


async def _client(settings: Settings, fleet: FleetService) -> AsyncIterator[httpx.AsyncClient]:
    app = create_app(settings, service=fleet)
    async with (
        app.router.lifespan_context(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://test") as c,
    ):
        yield c


@pytest.fixture
async def client(settings: Settings, fleet: FleetService) -> AsyncIterator[httpx.AsyncClient]:
    async for c in _client(settings, fleet):
        yield c


@pytest.fixture
async def auth_client(settings: Settings, fleet: FleetService) -> AsyncIterator[httpx.AsyncClient]:
    async for c in _client(settings.model_copy(update={"api_token": SecretStr(TOKEN)}), fleet):
        yield c
