"""Server-Sent Events of robot states and task changes.

The service calls listeners from its own (Zenoh or worker) threads; each stream hands
events to the event loop with ``loop.call_soon_threadsafe`` and turns them into SSE frames
there. Robot states are coalesced per robot to at most ``robot_hz`` frames a second (the
latest state always goes out, and a change of robot status goes out at once); task changes
are never dropped. A client that falls ``max_backlog`` frames behind is disconnected
(``event: overflow``) rather than buffered without bound: it reconnects and gets a fresh
snapshot.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator

from api.deps import FleetAPI
from api.schemas import RobotOut, TaskOut
from fleet.core.tasks import FleetEvent, RobotEvent, RobotStatus, RobotView, TaskEvent

_log = logging.getLogger(__name__)

KEEPALIVE_S = 15.0


def sse_frame(event: str, data: str) -> str:
    """One SSE frame; ``data`` must be a single line (compact JSON is)."""
    return f"event: {event}\ndata: {data}\n\n"


class _Stream:
    """One client's subscription: coalesces robot states, queues frames for the generator."""

    def __init__(
        self, loop: asyncio.AbstractEventLoop, min_interval: float, max_backlog: int
    ) -> None:
        self._loop = loop
        self._min_interval = min_interval
        self._max_backlog = max_backlog
        self.frames: asyncio.Queue[str | None] = asyncio.Queue()
        self._last_sent: dict[str, tuple[float, RobotStatus]] = {}
        self._pending: dict[str, RobotView] = {}
        self._timers: dict[str, asyncio.TimerHandle] = {}
        self._ended = False

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
        if self.frames.qsize() >= self._max_backlog:
            _log.warning("event stream client too slow: disconnecting it")
            self.frames.put_nowait(sse_frame("overflow", '{"detail": "client too slow"}'))
            self.end()
            return
        self.frames.put_nowait(frame)

    def end(self) -> None:
        """Finish the stream after the frames already queued."""
        if not self._ended:
            self._ended = True
            self.frames.put_nowait(None)
        for timer in self._timers.values():
            timer.cancel()
        self._timers.clear()


class EventHub:
    """Creates event streams and ends them all when the server shuts down."""

    def __init__(self, robot_hz: float = 10.0, max_backlog: int = 10_000) -> None:
        self._min_interval = 1.0 / robot_hz
        self._max_backlog = max_backlog
        self._streams: set[_Stream] = set()
        self._closed = False

    @property
    def active(self) -> int:
        return len(self._streams)

    def close(self) -> None:
        """End every open stream (graceful shutdown must not wait for endless responses)."""
        self._closed = True
        for stream in list(self._streams):
            stream.end()

    async def stream(self, service: FleetAPI) -> AsyncIterator[str]:
        """SSE frames: a snapshot of every robot, then live robot and task events.

        The listener is removed however the stream ends: client disconnect (the response
        task is cancelled), server shutdown, or overflow.
        """
        stream = _Stream(asyncio.get_running_loop(), self._min_interval, self._max_backlog)
        unsubscribe = service.add_listener(stream.on_event)  # before the snapshot: no gap
        self._streams.add(stream)
        try:
            if self._closed:
                return
            yield "retry: 2000\n\n"
            for robot in await asyncio.to_thread(service.robots):
                stream.accept(RobotEvent(robot=robot))
            while True:
                try:
                    frame = await asyncio.wait_for(stream.frames.get(), KEEPALIVE_S)
                except TimeoutError:
                    yield ": keepalive\n\n"
                    continue
                if frame is None:
                    return
                yield frame
        finally:
            self._streams.discard(stream)
            stream.end()
            unsubscribe()
