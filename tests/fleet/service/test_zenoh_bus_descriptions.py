"""The Zenoh bus's description logic on a stand-in session (no network): whom it asks, how
often, and what it hands to the sink. The real thing: ``tests/integration/test_descriptions``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh
from support import FakePayload, FakeSample

from fleet.core.params import RobotProfile
from fleet.core.wire import Keys, Pose, RobotDescription, RobotMode, RobotState, encode
from fleet.service.zenoh_bus import ZenohFleetBus

KEYS = Keys()


class _Handle:
    def undeclare(self) -> None:
        pass


class _Liveliness:
    def declare_subscriber(self, key: str, callback: Any, history: bool = False) -> _Handle:
        return _Handle()

    def declare_token(self, key: str) -> _Handle:
        return _Handle()


class FakeSession:
    """Records ``get`` calls (key, callback); declares nothing real."""

    def __init__(self) -> None:
        self.gets: list[tuple[str, Callable[[Any], None]]] = []
        self.subscribers: dict[str, Callable[[Any], None]] = {}

    def declare_subscriber(self, key: str, callback: Callable[[Any], None]) -> _Handle:
        self.subscribers[key] = callback
        return _Handle()

    def declare_queryable(self, key: str, callback: Any) -> _Handle:
        return _Handle()

    def liveliness(self) -> _Liveliness:
        return _Liveliness()

    def get(self, key: str, callback: Callable[[Any], None], timeout: float = 0.0) -> None:
        self.gets.append((key, callback))


@dataclass
class _Reply:
    ok: FakeSample | None


class Sink:
    def __init__(self) -> None:
        self.descriptions: list[RobotDescription] = []
        self.states: list[str] = []

    def on_state(self, state: RobotState) -> None:
        self.states.append(state.robot_id)

    def on_robot_alive(self, robot_id: str) -> None:
        pass

    def on_robot_gone(self, robot_id: str) -> None:
        pass

    def on_description(self, description: RobotDescription) -> None:
        self.descriptions.append(description)

    def on_control(self, command: Any) -> None:
        pass

    def obstacles(self) -> list[Any]:
        return []


def _bus() -> tuple[ZenohFleetBus, FakeSession, Sink]:
    session, sink = FakeSession(), Sink()
    bus = ZenohFleetBus(session, KEYS)  # type: ignore[arg-type]
    bus.start(sink)
    return bus, session, sink


def _state(rid: str) -> FakeSample:
    s = RobotState(robot_id=rid, seq=0, stamp=0.0, pose=Pose(x=0.0, y=0.0), mode=RobotMode.IDLE)
    return FakeSample(KEYS.state(rid), FakePayload(encode(s)))


def test_a_robot_is_asked_once_per_token_and_again_after_it_comes_back() -> None:
    bus, session, _ = _bus()
    alive = FakeSample(KEYS.alive("r1"), FakePayload(b""))
    states = session.subscribers[KEYS.all_states]
    bus._on_alive(alive)  # type: ignore[arg-type]
    for _ in range(5):
        states(_state("r1"))
    assert [k for k, _ in session.gets] == [KEYS.description("r1")]
    bus._on_alive(FakeSample(KEYS.alive("r1"), FakePayload(b""), zenoh.SampleKind.DELETE))  # type: ignore[arg-type]
    states(_state("r1"))  # first state of its next life
    assert [k for k, _ in session.gets] == [KEYS.description("r1")] * 2
    assert bus.counters["description_queries"] == 2
    bus.close()


def test_answers_and_puts_reach_the_sink_and_bad_ones_are_dropped_and_counted() -> None:
    bus, session, sink = _bus()
    session.subscribers[KEYS.all_states](_state("r1"))
    ((_, reply),) = session.gets
    good = RobotDescription.of("r1", RobotProfile(), model="m")
    reply(_Reply(FakeSample(KEYS.description("r1"), FakePayload(encode(good)))))
    reply(_Reply(None))  # an error reply (e.g. a timeout): counted
    put = session.subscribers[KEYS.all_descriptions]
    put(FakeSample(KEYS.description("r1"), FakePayload(b"not json")))
    other = RobotDescription.of("r2", RobotProfile())
    put(FakeSample(KEYS.description("r1"), FakePayload(encode(other))))  # r2's on r1's key
    assert sink.descriptions == [good]
    counters = bus.counters
    assert counters["description_query_errors"] == 1
    assert counters["description_key_mismatch"] == 1
    assert sum(n for k, n in counters.items() if k.startswith("dropped_")) == 1
    bus.close()
