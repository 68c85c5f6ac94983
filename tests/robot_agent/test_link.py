"""LinkMonitor: when is a robot in touch with the fleet's Zenoh network (no real session)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fleet.core.wire import Keys
from robot_agent.link import LinkMonitor


@dataclass
class FakeClock:
    t: float = 100.0

    def __call__(self) -> float:
        return self.t


@dataclass
class FakeInfo:
    routers: list[str] = field(default_factory=lambda: ["router-zid"])

    def routers_zid(self) -> list[str]:
        return list(self.routers)


@dataclass
class FakeReply:
    ok: object | None = "echo"


@dataclass
class FakeSession:
    """The parts of a zenoh.Session the monitor uses; queries are answered by hand."""

    info: FakeInfo = field(default_factory=FakeInfo)
    queries: list[tuple[str, Callable[[Any], None]]] = field(default_factory=list)

    def get(self, key: str, callback: Callable[[Any], None], timeout: float) -> None:
        self.queries.append((key, callback))


def test_without_a_session_the_link_is_always_up() -> None:
    clock = FakeClock()
    monitor = LinkMonitor(None, Keys(), 1.0, clock=clock)
    clock.t += 1e6
    assert monitor.ok()


def test_silence_loses_the_link_once_and_traffic_restores_it() -> None:
    clock, session = FakeClock(), FakeSession()
    monitor = LinkMonitor(session, Keys(), 3.0, clock=clock)
    assert monitor.ok()
    clock.t += 3.5  # nothing heard for longer than the timeout
    assert not monitor.ok() and not monitor.ok()
    assert monitor.losses == 1  # counted once per loss, not per poll
    monitor.heard()
    assert monitor.ok()


def test_no_router_is_a_lost_link_for_a_client_but_not_for_a_peer() -> None:
    clock = FakeClock()
    client = LinkMonitor(FakeSession(FakeInfo(routers=[])), Keys(), 3.0, clock=clock)
    peer = LinkMonitor(
        FakeSession(FakeInfo(routers=[])), Keys(), 3.0, clock=clock, check_router=False
    )
    assert not client.ok()
    assert peer.ok()


def test_the_echo_reply_of_the_router_keeps_a_lone_robot_linked() -> None:
    clock, session = FakeClock(), FakeSession()
    monitor = LinkMonitor(session, Keys(), 3.0, clock=clock)
    assert monitor.ok()
    assert [key for key, _ in session.queries] == ["@/router-zid/router"]
    clock.t += 0.5
    monitor.ok()
    assert len(session.queries) == 1  # at most one echo per echo interval (timeout / 3)
    clock.t += 0.6
    monitor.ok()
    assert len(session.queries) == 2
    clock.t += 2.5  # 3.6 s since the start: lost, unless the echo answers
    session.queries[-1][1](FakeReply())
    assert monitor.ok()
    session.queries[-1][1](FakeReply(ok=None))  # an error reply is no evidence
    clock.t += 3.5
    assert not monitor.ok()


def test_peers_heard_elsewhere_count_as_traffic() -> None:
    clock, heard_at = FakeClock(), [100.0]
    monitor = LinkMonitor(
        FakeSession(), Keys(), 3.0, clock=clock, heard_elsewhere=lambda: heard_at[0]
    )
    clock.t += 10.0
    heard_at[0] = clock.t - 1.0  # a peer's state arrived a second ago
    assert monitor.ok()
