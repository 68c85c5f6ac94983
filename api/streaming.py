"""Server-Sent Events of robot states and task changes, bounded in clients and memory.

The service calls listeners from its own (Zenoh or worker) threads; each subscription hands
events to the event loop with ``loop.call_soon_threadsafe`` and turns them into SSE frames
there. Robot states are coalesced per robot to at most ``robot_hz`` frames a second (the
latest state always goes out, and a change of robot status goes out at once); task changes
are never dropped.

Bounds (settings ``api_sse_*``): at most ``max_clients`` streams are open at once (the route
answers 503 beyond); each client has a queue of at most ``max_backlog`` frames. A client
that falls that far behind is dropped with a log line (``event: overflow`` is its last
frame: it reconnects and gets a fresh snapshot); if it does not even read that within
:data:`DROP_GRACE_S`, its response is cancelled and the connection closed, so a stalled
client never holds a slot.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Callable

import anyio
from starlette.responses import StreamingResponse
from starlette.types import Receive, Scope, Send

from api.deps import FleetAPI
from api.schemas import RobotOut, TaskOut
from fleet.core.tasks import FleetEvent, RobotEvent, RobotStatus, RobotView, TaskEvent

_log = logging.getLogger(__name__)

KEEPALIVE_S = 15.0
#: A dropped client that reads nothing for this long [s] is disconnected.
DROP_GRACE_S = 5.0
#: Frames joined into one write to the socket (fewer, larger sends under load).
FRAMES_PER_WRITE = 256


def sse_frame(event: str, data: str) -> str:
    """One SSE frame; ``data`` must be a single line (compact JSON is)."""
    return f"event: {event}\ndata: {data}\n\n"


class TooManyClients(Exception):
    """Every event-stream slot is taken (the route answers 503)."""


class Subscription:
    """One client's stream: coalesces robot states and queues at most ``max_backlog``
    frames for :meth:`frames`. Made by :meth:`EventHub.subscribe`; :meth:`close` it."""

    def __init__(
        self,
        service: FleetAPI,
        min_interval: float,
        max_backlog: int,
        client: str,
        on_close: Callable[[Subscription], None],
    ) -> None:
        self._loop = asyncio.get_running_loop()
        self._service = service
        self._min_interval = min_interval
        self._max_backlog = max_backlog
        self.client = client
        self._on_close = on_close
        self.queue: asyncio.Queue[str | None] = asyncio.Queue()
        #: Set when the client was dropped for falling ``max_backlog`` frames behind.
        self.dropped = asyncio.Event()
        self._last_sent: dict[str, tuple[float, RobotStatus]] = {}
        self._pending: dict[str, RobotView] = {}
        self._timers: dict[str, asyncio.TimerHandle] = {}
        self._ended = False
        self._closed = False
        self._unsubscribe = service.add_listener(self.on_event)  # before the snapshot: no gap

    # --- any thread ---------------------------------------------------------------
    def on_event(self, event: FleetEvent) -> None:
        """The service's listener; runs on the service's threads."""
        with contextlib.suppress(RuntimeError):  # loop already closed: nobody is listening
            self._loop.call_soon_threadsafe(self.accept, event)

    # --- event loop only ----------------------------------------------------------
    def accept(self, event: FleetEvent) -> None:
        if self._ended:
            return
        if isinstance(event, TaskEvent):
            self._put(sse_frame("task", TaskOut.of(event.task).model_dump_json()))
        elif isinstance(event, RobotEvent):
            self._robot(event.robot)

    def _robot(self, view: RobotView) -> None:
        rid = view.robot_id
        now = self._loop.time()
        last = self._last_sent.get(rid)
        if last is None or last[1] != view.status or now - last[0] >= self._min_interval:
            self._pending.pop(rid, None)
            timer = self._timers.pop(rid, None)
            if timer is not None:
                timer.cancel()
            self._send_robot(view, now)
            return
        self._pending[rid] = view  # latest wins
        if rid not in self._timers:
            delay = self._min_interval - (now - last[0])
            self._timers[rid] = self._loop.call_later(delay, self._flush, rid)

    def _flush(self, rid: str) -> None:
        self._timers.pop(rid, None)
        view = self._pending.pop(rid, None)
        if view is not None and not self._ended:
            self._send_robot(view, self._loop.time())

    def _send_robot(self, view: RobotView, now: float) -> None:
        self._last_sent[view.robot_id] = (now, view.status)
        self._put(sse_frame("robot", RobotOut.of(view).model_dump_json()))

    def _put(self, frame: str) -> None:
        if self.queue.qsize() >= self._max_backlog:
            _log.warning(
                "event stream client %s fell %d frames behind: dropping it",
                self.client,
                self._max_backlog,
            )
            self.queue.put_nowait(sse_frame("overflow", '{"detail": "client too slow"}'))
            self.dropped.set()
            self.end()
            return
        self.queue.put_nowait(frame)

    def end(self) -> None:
        """Finish the stream after the frames already queued."""
        if not self._ended:
            self._ended = True
            self.queue.put_nowait(None)
        for timer in self._timers.values():
            timer.cancel()
        self._timers.clear()

    def close(self) -> None:
        """Stop listening and free the client's slot (idempotent; event loop only)."""
        self.end()
        if not self._closed:
            self._closed = True
            self._unsubscribe()
            self._on_close(self)

    async def frames(self) -> AsyncIterator[str]:
        """SSE text: ``retry``, a snapshot of every robot, then live robot and task events
        (several frames per chunk when they queue up), keepalive comments when idle.

        A stream ended before its first frame (dropped while the response was starting, or
        the server shutting down) still sends what it queued, the overflow notice included,
        and ends."""
        yield "retry: 2000\n\n"
        if not self._ended:
            for robot in await asyncio.to_thread(self._service.robots):
                self.accept(RobotEvent(robot=robot))
        while True:
            try:
                frame = await asyncio.wait_for(self.queue.get(), KEEPALIVE_S)
            except TimeoutError:
                yield ": keepalive\n\n"
                continue
            chunk: list[str] = []
            while frame is not None:
                chunk.append(frame)
                if len(chunk) == FRAMES_PER_WRITE or self.queue.empty():
                    break
                frame = self.queue.get_nowait()
            if chunk:
                yield "".join(chunk)
            if frame is None:
                return


class EventHub:
    """Opens event streams (at most ``max_clients`` at once) and ends them all when the
    server shuts down."""

    def __init__(
        self, robot_hz: float = 10.0, max_backlog: int = 2000, max_clients: int = 32
    ) -> None:
        self._min_interval = 1.0 / robot_hz
        self._max_backlog = max_backlog
        self.max_clients = max_clients
        self._streams: set[Subscription] = set()
        self._closed = False

    @property
    def active(self) -> int:
        """Open streams."""
        return len(self._streams)

    def close(self) -> None:
        """End every open stream (graceful shutdown must not wait for endless responses)."""
        self._closed = True
        for stream in list(self._streams):
            stream.end()

    def subscribe(self, service: FleetAPI, client: str = "client") -> Subscription:
        """A new stream listening to ``service`` (event loop only); raises
        :class:`TooManyClients` when ``max_clients`` are open. ``client`` names it in logs."""
        if len(self._streams) >= self.max_clients:
            raise TooManyClients(
                f"{len(self._streams)} event streams are open, the most this server keeps "
                "(api_sse_max_clients): retry later"
            )
        stream = Subscription(
            service, self._min_interval, self._max_backlog, client, self._streams.discard
        )
        self._streams.add(stream)
        if self._closed:
            stream.end()
        return stream

    async def stream(self, service: FleetAPI) -> AsyncIterator[str]:
        """:meth:`subscribe` and its frames; closed however the iteration ends."""
        stream = self.subscribe(service)
        try:
            async for chunk in stream.frames():
                yield chunk
        finally:
            stream.close()


class EventStreamResponse(StreamingResponse):
    """The ``text/event-stream`` response of one subscription. It closes the subscription
    however the response ends (even if it never started; a client that goes away ends it
    at once: Starlette listens for the disconnect under uvicorn's ASGI 2.3), and cuts off a
    dropped client that has not read its last frame after :data:`DROP_GRACE_S`."""

    def __init__(self, stream: Subscription) -> None:
        super().__init__(
            stream.frames(),
            media_type="text/event-stream",
            headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
        )
        self._stream = stream

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        try:
            async with anyio.create_task_group() as group:

                async def cut_off_when_dropped() -> None:
                    await self._stream.dropped.wait()
                    await anyio.sleep(DROP_GRACE_S)
                    _log.warning("event stream client %s stalled: closing", self._stream.client)
                    group.cancel_scope.cancel()

                group.start_soon(cut_off_when_dropped)
                await super().__call__(scope, receive, send)
                group.cancel_scope.cancel()
        finally:
            self._stream.close()
