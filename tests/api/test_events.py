"""Server-Sent Events: snapshot, task events, per-robot coalescing, unsubscribe, shutdown."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest

from api.streaming import EventHub
from fleet.core.tasks import (
    FleetEvent,
    RobotEvent,
    RobotStatus,
    RobotView,
    Task,
    TaskEvent,
    TaskRequest,
)
from fleet.core.wire import Pose

pytestmark = pytest.mark.anyio


class Source:
    """Just what the hub uses of the service: listeners and a robot snapshot."""

    def __init__(self, robots: list[RobotView] = []) -> None:  # noqa: B006
        self.listeners: list[Callable[[FleetEvent], None]] = []
        self._robots = list(robots)

    def robots(self) -> list[RobotView]:
        return self._robots

    def add_listener(self, listener: Callable[[FleetEvent], None]) -> Callable[[], None]:
        self.listeners.append(listener)
        return lambda: self.listeners.remove(listener)

    def emit(self, event: FleetEvent) -> None:
        for listener in list(self.listeners):
            listener(event)


def task_event(x: float) -> TaskEvent:
    task = Task(id=f"t{x}", request=TaskRequest(goal=Pose(x=x, y=0.0)), created_at=0, updated_at=0)
    return TaskEvent(task=task)


def parse(frame: str) -> tuple[str, dict[str, Any]]:
    lines = dict(line.split(": ", 1) for line in frame.strip().splitlines())
    return lines["event"], json.loads(lines["data"])


async def next_frame(stream: AsyncIterator[str]) -> str:
    while True:
        frame = await asyncio.wait_for(anext(stream), 5.0)
        if not frame.startswith((":", "retry:")):
            return frame


def view(robot_id: str, x: float, status: RobotStatus = RobotStatus.DRIVING) -> RobotView:
    return RobotView(robot_id=robot_id, status=status, pose=Pose(x=x, y=0.0), last_seen=0.0)


async def test_snapshot_then_task_events_from_other_threads() -> None:
    fleet = Source([view("r1", x=1.0, status=RobotStatus.IDLE)])
    hub = EventHub()
    stream = hub.stream(fleet)
    try:
        assert await anext(stream) == "retry: 2000\n\n"
        kind, data = parse(await next_frame(stream))
        assert (kind, data["robot_id"], data["pose"]["x"]) == ("robot", "r1", 1.0)

        worker = threading.Thread(target=fleet.emit, args=(task_event(2.0),))
        worker.start()
        worker.join()
        kind, data = parse(await next_frame(stream))
        assert kind == "task"
        assert data["status"] == "queued"
        assert data["goal"] == {"x": 2.0, "y": 0.0, "theta": 0.0}
    finally:
        await stream.aclose()
    assert fleet.listeners == []  # unsubscribed


async def test_robot_states_are_coalesced_and_the_latest_is_delivered() -> None:
    fleet = Source()
    hub = EventHub(robot_hz=10.0)
    stream = hub.stream(fleet)
    try:
        await anext(stream)  # retry
        listener = fleet.listeners[0]

        def burst() -> None:
            for i in range(200):
                listener(RobotEvent(robot=view("r1", x=i / 100)))

        worker = threading.Thread(target=burst)
        worker.start()
        worker.join()
        first = parse(await next_frame(stream))[1]
        assert first["pose"]["x"] == 0.0  # the first goes out at once
        latest = parse(await next_frame(stream))[1]
        assert latest["pose"]["x"] == 1.99  # then only the latest of the burst
        # A change of status is not held back.
        listener(RobotEvent(robot=view("r1", x=5.0, status=RobotStatus.ARRIVED)))
        arrived = parse(await next_frame(stream))[1]
        assert arrived["status"] == "arrived"
    finally:
        await stream.aclose()


async def test_hub_close_ends_open_streams() -> None:
    fleet = Source()
    hub = EventHub()
    stream = hub.stream(fleet)
    await anext(stream)
    assert hub.active == 1
    hub.close()
    with pytest.raises(StopAsyncIteration):
        await asyncio.wait_for(anext(stream), 5.0)
    assert hub.active == 0
    assert fleet.listeners == []


async def test_slow_client_is_disconnected_not_buffered() -> None:
    fleet = Source()
    hub = EventHub(max_backlog=5)
    stream = hub.stream(fleet)
    await anext(stream)
    for x in range(10):
        fleet.emit(task_event(float(x)))
    await asyncio.sleep(0.05)  # let the loop run the thread-safe callbacks
    frames = [frame async for frame in stream]
    assert [parse(f)[0] for f in frames] == ["task"] * 5 + ["overflow"]
    assert fleet.listeners == []
