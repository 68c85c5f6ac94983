"""API tests: the real app (routes, validation, auth, errors) over ASGI, with the real
fleet service and a real SQLite store; only the Zenoh bus is the in-memory one. Where the
socket matters (streams, cut-off connections), :func:`serving` runs the app in uvicorn."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import AsyncIterator, Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
import uvicorn
from fastapi import FastAPI
from pydantic import SecretStr
from support import wait_for

from api.app import create_app
from api.server import bind_socket
from fleet.core.tasks import FleetEvent, RobotView, Task, TaskStatus
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
def store(tmp_path: Path) -> Iterator[SqliteTaskStore]:
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    try:
        yield store
    finally:
        store.close()


@pytest.fixture
def fleet(settings: Settings, bus: MemoryBus, store: SqliteTaskStore) -> Iterator[FleetService]:
    with FleetService(settings, bus, store) as service:
        yield service


def add_robot(bus: MemoryBus, robot_id: str, x: float = 0.0, y: float = 0.0) -> None:
    """A robot appears: liveliness token, then an idle state."""
    bus.robot_alive(robot_id)
    bus.deliver_state(
        RobotState(
            robot_id=robot_id, seq=0, stamp=time.time(), pose=Pose(x=x, y=y), mode=RobotMode.IDLE
        )
    )


def drive(fleet: FleetService, bus: MemoryBus, task_id: str, steps: range) -> None:
    """Robot r1 drives ``task_id`` once assigned: a state for each of the ``steps``."""
    wait_for(lambda: fleet.task(task_id).status != TaskStatus.QUEUED, 30, "the task to be assigned")
    for k in steps:
        s = k / 40
        bus.deliver_state(
            RobotState(
                robot_id="r1",
                seq=k,
                stamp=time.time(),
                pose=Pose(x=2.0 * s, y=1.0 * s, theta=s),
                u=0.5,
                omega=0.2,
                mode=RobotMode.DRIVING,
                task_id=task_id,
            )
        )


async def driven_task(
    client: httpx.AsyncClient, fleet: FleetService, bus: MemoryBus, steps: range
) -> str:
    """A task for a new robot r1, submitted over ``client`` and driven (:func:`drive`)."""
    add_robot(bus, "r1", 0.0, 0.0)
    body = {"goal": {"x": 2.0, "y": 1.0, "theta": 1.0}, "robot_id": "r1"}
    task_id: str = (await client.post("/tasks", json=body)).json()["id"]
    drive(fleet, bus, task_id, steps)
    return task_id


async def api_client(
    settings: Settings, fleet: FleetService, store: SqliteTaskStore
) -> AsyncIterator[httpx.AsyncClient]:
    """An HTTP client of the app on ``fleet`` (over ASGI), its lifespan running."""
    app = create_app(settings, service=fleet, store=store)
    async with (
        app.router.lifespan_context(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://test") as c,
    ):
        yield c


@pytest.fixture
async def client(
    settings: Settings, fleet: FleetService, store: SqliteTaskStore
) -> AsyncIterator[httpx.AsyncClient]:
    async for c in api_client(settings, fleet, store):
        yield c


@pytest.fixture
async def auth_client(
    settings: Settings, fleet: FleetService, store: SqliteTaskStore
) -> AsyncIterator[httpx.AsyncClient]:
    with_token = settings.model_copy(update={"api_token": SecretStr(TOKEN)})
    async for c in api_client(with_token, fleet, store):
        yield c


class EventSource:
    """Just what the event hub (and the metrics at start) use of the service: listeners, a
    robot snapshot, no tasks."""

    def __init__(self, robots: list[RobotView] = []) -> None:  # noqa: B006
        self.listeners: list[Callable[[FleetEvent], None]] = []
        self._robots = list(robots)

    def robots(self) -> list[RobotView]:
        return self._robots

    def tasks(self, status: TaskStatus | None = None, robot_id: str | None = None) -> list[Task]:
        return []  # the app's metrics read the active tasks at start: none here

    def add_listener(self, listener: Callable[[FleetEvent], None]) -> Callable[[], None]:
        self.listeners.append(listener)
        return lambda: self.listeners.remove(listener)

    def emit(self, event: FleetEvent) -> None:
        for listener in list(self.listeners):
            listener(event)


@contextmanager
def serving(app: FastAPI, send_buffer: int | None = None) -> Iterator[int]:
    """``app`` served by uvicorn on a free loopback port (in a thread); yields the port.
    ``send_buffer`` [bytes] sets SO_SNDBUF of the listening socket, which the accepted
    connections inherit (so a client that stops reading blocks the server soon)."""
    sock = bind_socket("127.0.0.1", 0)
    if send_buffer is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, send_buffer)
    server = uvicorn.Server(
        uvicorn.Config(app, log_config=None, lifespan="on", timeout_graceful_shutdown=5)
    )
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]})
    thread.start()
    try:
        wait_for(lambda: server.started or not thread.is_alive(), 30, "uvicorn to start")
        assert server.started, "uvicorn did not start"
        yield sock.getsockname()[1]
    finally:
        app.state.events.close()  # endless streams would hold up the shutdown
        server.should_exit = True
        thread.join(30)
        sock.close()
