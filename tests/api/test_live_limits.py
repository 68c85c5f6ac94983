"""The API's bounds over real sockets (uvicorn in a thread): event-stream slots and slow
clients, and bodies refused before they are read."""

from __future__ import annotations

import logging
import socket
from collections.abc import Iterator
from contextlib import closing, contextmanager

import httpx
import pytest
from support import wait_for

from api.app import create_app
from api.metrics import FleetMetrics
from api.schemas import TaskOut
from api.streaming import EventHub, sse_frame
from fleet.core.tasks import Task, TaskEvent, TaskRequest
from fleet.core.wire import Pose
from fleet.io.settings import Settings, load_settings
from fleet.service.store import MemoryTaskStore
from tests.api.conftest import EventSource, serving

pytestmark = pytest.mark.integration


@contextmanager
def raw_get(port: int, path: str, receive_buffer: int | None = None) -> Iterator[socket.socket]:
    """A GET request on a raw socket, response unread (``receive_buffer``: SO_RCVBUF)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    with closing(sock):
        if receive_buffer is not None:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        sock.connect(("127.0.0.1", port))
        sock.sendall(f"GET {path} HTTP/1.1\r\nHost: test\r\n\r\n".encode())
        yield sock


def read_to_the_end(sock: socket.socket) -> bytes:
    """Everything until the server closes the connection (fails the test after 30 s)."""
    sock.settimeout(30)
    data = b""
    try:
        while chunk := sock.recv(1 << 16):
            data += chunk
    except ConnectionResetError:
        pass  # closed with data unread on its side: closed all the same
    return data


def read_until(sock: socket.socket, marker: bytes) -> bytes:
    """What the server sent up to and including ``marker`` (fails the test after 30 s)."""
    sock.settimeout(30)
    data = b""
    while marker not in data:
        chunk = sock.recv(1)
        assert chunk, f"the connection closed before {marker!r}"
        data += chunk
    return data


def big_task_event(k: int) -> TaskEvent:
    """A task change whose SSE frame is ~64 KB (a long reason)."""
    task = Task(
        id=f"t{k}",
        request=TaskRequest(goal=Pose(x=1.0, y=0.0)),
        reason="x" * 65_536,
        created_at=0,
        updated_at=0,
    )
    return TaskEvent(task=task)


def app_on(source: EventSource, settings: Settings) -> tuple[object, EventHub]:
    app = create_app(settings, service=source, store=MemoryTaskStore())  # type: ignore[arg-type]
    return app, app.state.events


def test_a_client_that_stops_reading_is_dropped_and_cut_off(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.WARNING, logger="api.streaming")
    settings = load_settings(api_sse_queue_frames=16)
    source = EventSource()
    app, hub = app_on(source, settings)
    with serving(app, send_buffer=4096) as port, raw_get(port, "/events", 4096) as sock:  # type: ignore[arg-type]
        wait_for(lambda: hub.active == 1, 30, "the stream to open")
        head = read_until(sock, b"retry: 2000")  # the body has started
        assert head.startswith(b"HTTP/1.1 200")
        # 100 frames of 64 KB at once: 16 fit the queue, the client is dropped, and the
        # 1 MB of queued frames cannot reach a client that reads nothing: cut off.
        for k in range(100):
            source.emit(big_task_event(k))
        wait_for(lambda: hub.active == 0, 60, "the stalled client to be cut off")
        streams = [
            f
            for f in source.listeners
            if not isinstance(getattr(f, "__self__", None), FleetMetrics)
        ]
        assert streams == []  # the client's listener went (the app's metrics listen on)
        assert "fell 16 frames behind: dropping it" in caplog.text
        received = read_to_the_end(sock)
    # Either its writes blocked and the server cut it off after the grace, or the socket's
    # and the transport's buffers took the queue and the stream ended on its last frame,
    # the overflow notice (which one is the kernel's choice, not the server's).
    assert "stalled: closing" in caplog.text or b"event: overflow" in received
    # never more than the queue held, plus the one frame the sender had already taken
    # from it when the rest arrived (whether it had is a race: 16 or 17 frames come)
    frame = len(sse_frame("task", TaskOut.of(big_task_event(0).task).model_dump_json()))
    assert len(received) < (16 + 1) * frame + 4096  # + headers, snapshot, overflow frame


def test_event_stream_slots_are_capped_and_freed_when_a_client_leaves() -> None:
    settings = load_settings(api_sse_max_clients=1)
    source = EventSource()
    app, hub = app_on(source, settings)
    with serving(app) as port:  # type: ignore[arg-type]
        with raw_get(port, "/events"):
            wait_for(lambda: hub.active == 1, 30, "the first stream to open")
            refused = httpx.get(f"http://127.0.0.1:{port}/events", timeout=10)
            assert refused.status_code == 503
            assert refused.headers["retry-after"] == "5"
        wait_for(lambda: hub.active == 0, 30, "the slot of the client that left")
        with (
            httpx.Client(timeout=10) as client,
            client.stream("GET", f"http://127.0.0.1:{port}/events") as admitted,
        ):
            assert admitted.status_code == 200
            assert next(admitted.iter_lines()) == "retry: 2000"


def test_an_oversized_declared_body_is_refused_unread_and_the_connection_closed() -> None:
    settings = load_settings(api_max_body_bytes=4096, api_token="secret")
    app, _ = app_on(EventSource(), settings)
    with serving(app) as port:  # type: ignore[arg-type]
        sock = socket.create_connection(("127.0.0.1", port))
        with closing(sock):
            head = (
                "POST /tasks HTTP/1.1\r\nHost: test\r\nContent-Type: application/json\r\n"
                f"Content-Length: {100 * 2**20}\r\n\r\n"
            )
            sock.sendall(head.encode() + b'{"goal": ')  # 100 MB announced, 9 bytes sent
            response = read_to_the_end(sock)  # answered and closed without the rest
    assert response.startswith(b"HTTP/1.1 413")
    assert b"larger than 4096 bytes" in response
