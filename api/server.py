"""Run the API with uvicorn, programmatically: bind checks, readiness, graceful shutdown.

* Binds 127.0.0.1 by default and refuses a non-loopback address without an API token.
* The listening socket is bound here, before uvicorn starts, so a busy port is a clear
  error and ``--port 0`` resolves to a real port that the ready line reports.
* SIGINT / SIGTERM stop the server gracefully: open event streams are ended first, then
  in-flight requests finish, then the lifespan closes the fleet service, the store and the
  Zenoh session. The process then exits 0 (a second Ctrl-C forces the exit).
* The event loop is uvloop's (:func:`run_loop`) and uvicorn parses HTTP with httptools
  (its ``http="auto"`` picks it when installed; the ``server`` extra brings both): the
  requests' Python work shares one GIL with the Zenoh callbacks and the service's threads,
  and a request costs less CPU there than on asyncio's loop and h11 (``bench api``:
  docs/benchmarks.md). Without them (a platform uvloop does not support) it runs on
  asyncio's loop and h11, as before.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import signal
import socket
from collections.abc import Awaitable, Callable, Coroutine
from dataclasses import dataclass, field
from types import FrameType
from typing import Any, TypeVar

import uvicorn
from fastapi import FastAPI

from api.app import create_app
from fleet.io.heap import freeze_startup_heap, limit_arenas
from fleet.io.settings import Settings
from fleet.service.store_open import check_store

_log = logging.getLogger(__name__)

_T = TypeVar("_T")


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback IP addresses; any other name counts as exposed."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_bind(settings: Settings) -> None:
    """Raise ``ValueError`` if the API would be exposed beyond this host without a token."""
    if not is_loopback(settings.api_host) and settings.api_token is None:
        raise ValueError(
            f"refusing to serve on non-loopback address {settings.api_host!r} without an API "
            "token: set PARKFLEET_API_TOKEN (clients then send 'Authorization: Bearer "
            "<token>'), or bind 127.0.0.1"
        )


def bind_socket(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (``port`` 0: any free port)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    # proto=IPPROTO_TCP matters: asyncio only sets TCP_NODELAY on accepted sockets whose
    # proto says TCP (socket.create_server leaves it 0), and without it Nagle + delayed ACK
    # add ~40 ms to every response uvicorn writes in several pieces.
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host.strip("[]"), port))
        sock.listen(2048)
    except OSError as exc:
        sock.close()
        raise ConnectionError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from exc
    return sock


@dataclass
class Running:
    """What ``on_ready`` gets: the app (its ``state.service`` is up) and the real addresses."""

    app: FastAPI
    url: str
    zenoh: list[str] = field(default_factory=list)


class _Server(uvicorn.Server):
    def __init__(
        self,
        config: uvicorn.Config,
        app: FastAPI,
        url: str,
        on_ready: Callable[[Running], Awaitable[None]] | None,
        on_shutdown: Callable[[], Awaitable[None]] | None,
    ) -> None:
        super().__init__(config)
        self._app = app
        self._url = url
        self._on_ready = on_ready
        self._on_shutdown = on_shutdown

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        await super().startup(sockets)
        if self.started:  # the fleet is open: what lives now, lives as long as the server
            _log.debug("%d objects exempt from collection", freeze_startup_heap())
        if self.started and self._on_ready is not None:
            await self._on_ready(
                Running(self._app, self._url, list(self._app.state.zenoh_locators))
            )

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        if self._on_shutdown is not None:
            await self._on_shutdown()
        self._app.state.events.close()  # endless SSE responses would stall the drain
        await super().shutdown(sockets)

    def handle_exit(self, sig: int, frame: FrameType | None) -> None:
        # Like uvicorn's, but without re-raising the signal after the graceful shutdown:
        # a stop by SIGINT/SIGTERM is a normal exit.
        if self.should_exit and sig == signal.SIGINT:
            self.force_exit = True
        else:
            self.should_exit = True


async def serve(
    settings: Settings,
    *,
    on_ready: Callable[[Running], Awaitable[None]] | None = None,
    on_shutdown: Callable[[], Awaitable[None]] | None = None,
    access_log: bool = False,
) -> int:
    """Serve until SIGINT/SIGTERM; 0 after a graceful stop, 1 if startup failed.

    Raises ``ValueError`` (exposed without a token) or ``ConnectionError`` (busy port,
    PostgreSQL store unreachable) before anything is opened.
    """
    check_bind(settings)
    check_store(settings)  # PostgreSQL unreachable: a clear error, before anything opens
    limit_arenas(settings.malloc_arenas)  # before the fleet's threads (fleet/io/heap.py)
    sock = bind_socket(settings.api_host, settings.api_port)
    try:
        host, port = sock.getsockname()[:2]
        shown = f"[{host}]" if ":" in host else host
        url = f"http://{shown}:{port}"
        if settings.advertise_url is None:  # what a standby names for this one when it leads
            settings = settings.model_copy(update={"advertise_url": url})
        app = create_app(settings)
        config = uvicorn.Config(
            app,
            log_config=None,  # keep the CLI's logging setup
            access_log=access_log,
            lifespan="on",
            timeout_graceful_shutdown=5,
            timeout_keep_alive=30,
        )
        server = _Server(config, app, url, on_ready, on_shutdown)
        await server.serve(sockets=[sock])
        if not server.started:
            error = getattr(app.state, "startup_error", None)
            raise ConnectionError(str(error) if error else "the API server failed to start")
        return 0
    finally:
        sock.close()


def _loop_factory() -> Callable[[], asyncio.AbstractEventLoop] | None:
    """uvloop's event loop when installed, else None (asyncio's default)."""
    try:
        import uvloop
    except ImportError:  # not on this platform: asyncio's loop
        return None
    return uvloop.new_event_loop


def run_loop(main: Coroutine[Any, Any, _T]) -> _T:
    """Run ``main`` (a server: :func:`serve`, the demo's) to the end on a fresh event loop,
    uvloop's when installed (the module docstring), as ``asyncio.run`` does."""
    with asyncio.Runner(loop_factory=_loop_factory()) as runner:
        return runner.run(main)


def run(settings: Settings, **kwargs: object) -> int:
    """``serve`` on a fresh event loop (the CLI's entry)."""
    return run_loop(serve(settings, **kwargs))  # type: ignore[arg-type]
