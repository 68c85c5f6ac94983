"""Server-Sent Events: snapshot, task events, per-robot coalescing, unsubscribe, shutdown,
and the bounds: clients (503 beyond), frames queued per client (slow clients dropped)."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import AsyncIterator
from typing import Any

import httpx
import pytest

from api.streaming import EventHub, TooManyClients
from fleet.core.tasks import (
    RobotEvent,
    RobotStatus,
    RobotView,
    Task,
    TaskEvent,
    TaskRequest,
)
from fleet.core.wire import Pose
from fleet.service.fleet_service import FleetService
from tests.api.conftest import EventSource

pytestmark = pytest.mark.anyio


def task_event(x: float) -> TaskEvent:
    task = Task(id=f"t{x}", request=TaskRequest(goal=Pose(x=x, y=0.0)), created_at=0, updated_at=0)
    return TaskEvent(task=task)


def parse(frame: str) -> tuple[str, dict[str, Any]]:
    lines = dict(line.split(": ", 1) for line in frame.strip().splitlines())
    return lines["event"], json.loads(lines["data"])


class Frames:
    """The event frames of a stream one at a time (one chunk of it may hold several)."""

    def __init__(self, stream: AsyncIterator[str]) -> None:
        self.stream = stream
        self._held: list[str] = []

    async def next(self) -> str:
        while not self._held:
            chunk = await asyncio.wait_for(anext(self.stream), 5.0)
            self._held = [
                frame + "\n\n"
                for frame in chunk.split("\n\n")
                if frame and not frame.startswith((":", "retry:"))
            ]
        return self._held.pop(0)


def view(robot_id: str, x: float, status: RobotStatus = RobotStatus.DRIVING) -> RobotView:
    return RobotView(robot_id=robot_id, status=status, pose=Pose(x=x, y=0.0), last_seen=0.0)


async def test_snapshot_then_task_events_from_other_threads() -> None:
    fleet = EventSource([view("r1", x=1.0, status=RobotStatus.IDLE)])
    hub = EventHub()
    stream = hub.stream(fleet)
    frames = Frames(stream)
    try:
        assert await anext(stream) == "retry: 2000\n\n"
        kind, data = parse(await frames.next())
        assert (kind, data["robot_id"], data["pose"]["x"]) == ("robot", "r1", 1.0)

        worker = threading.Thread(target=fleet.emit, args=(task_event(2.0),))
        worker.start()
        worker.join()
        kind, data = parse(await frames.next())
        assert kind == "task"
        assert data["status"] == "queued"
        assert data["goal"] == {"x": 2.0, "y": 0.0, "theta": 0.0}
    finally:
        await stream.aclose()
    assert fleet.listeners == []  # unsubscribed


async def test_robot_states_are_coalesced_and_the_latest_is_delivered() -> None:
    fleet = EventSource()
    hub = EventHub(robot_hz=10.0)
    stream = hub.stream(fleet)
    frames = Frames(stream)
    try:
        await anext(stream)  # retry
        listener = fleet.listeners[0]

        def burst() -> None:
            for i in range(200):
                listener(RobotEvent(robot=view("r1", x=i / 100)))

        worker = threading.Thread(target=burst)
        worker.start()
        worker.join()
        first = parse(await frames.next())[1]
        assert first["pose"]["x"] == 0.0  # the first goes out at once
        latest = parse(await frames.next())[1]
        assert latest["pose"]["x"] == 1.99  # then only the latest of the burst
        # A change of status is not held back.
        listener(RobotEvent(robot=view("r1", x=5.0, status=RobotStatus.ARRIVED)))
        arrived = parse(await frames.next())[1]
        assert arrived["status"] == "arrived"
    finally:
        await stream.aclose()


async def test_hub_close_ends_open_streams() -> None:
    fleet = EventSource()
    hub = EventHub()
    stream = hub.stream(fleet)
    await anext(stream)
    assert hub.active == 1
    hub.close()
    with pytest.raises(StopAsyncIteration):
        await asyncio.wait_for(anext(stream), 5.0)
    assert hub.active == 0
    assert fleet.listeners == []


async def test_slow_client_is_dropped_with_a_log_line_not_buffered(
    caplog: pytest.LogCaptureFixture,
) -> None:
    fleet = EventSource()
    hub = EventHub(max_backlog=5)
    stream = hub.stream(fleet)
    await anext(stream)
    # Scheduled on the loop now (call_soon_threadsafe), so all ten are accepted before the
    # stream's next read: the client is five frames behind when the sixth comes.
    for x in range(10):
        fleet.emit(task_event(float(x)))
    chunks = [chunk async for chunk in stream]
    frames = [f for f in "".join(chunks).split("\n\n") if f]
    assert [parse(f)[0] for f in frames] == ["task"] * 5 + ["overflow"]
    assert fleet.listeners == []
    assert hub.active == 0
    assert "fell 5 frames behind: dropping it" in caplog.text


async def test_a_client_dropped_before_its_stream_starts_still_gets_the_overflow_notice() -> None:
    fleet = EventSource()
    hub = EventHub(max_backlog=5)
    subscription = hub.subscribe(fleet)  # subscribed by the route, the body not yet started
    for x in range(10):
        subscription.accept(task_event(float(x)))  # a burst before the first frame
    try:
        chunks = [chunk async for chunk in subscription.frames()]
    finally:
        subscription.close()
    assert chunks[0] == "retry: 2000\n\n"
    frames = [f for f in "".join(chunks[1:]).split("\n\n") if f]
    assert [parse(f)[0] for f in frames] == ["task"] * 5 + ["overflow"]
    assert hub.active == 0


async def test_clients_beyond_the_cap_are_refused_until_one_leaves() -> None:
    fleet = EventSource()
    hub = EventHub(max_clients=2)
    first, second = hub.subscribe(fleet, "a"), hub.subscribe(fleet, "b")
    with pytest.raises(TooManyClients, match="2 event streams are open"):
        hub.subscribe(fleet, "c")
    assert len(fleet.listeners) == 2  # the refused one never listened
    first.close()
    first.close()  # idempotent
    third = hub.subscribe(fleet, "c")
    assert hub.active == 2
    for stream in (second, third):
        stream.close()
    assert hub.active == 0 and fleet.listeners == []


async def test_events_route_is_503_when_every_slot_is_taken(
    client: httpx.AsyncClient, fleet: FleetService
) -> None:
    hub: EventHub = client._transport.app.state.events  # type: ignore[attr-defined]
    held = [hub.subscribe(fleet, f"c{i}") for i in range(hub.max_clients)]
    try:
        r = await client.get("/events")
        assert r.status_code == 503
        assert "event streams are open" in r.json()["detail"]
        assert int(r.headers["retry-after"]) > 0
    finally:
        for stream in held:
            stream.close()
