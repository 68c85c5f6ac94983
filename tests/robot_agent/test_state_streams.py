"""The two state streams of a robot (peer cells, fleet rate) and the feed's cell
subscriptions, on a recording stand-in session (the real-Zenoh test is in
tests/integration/test_neighbourhood.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.wire import (
    Keys,
    Pose,
    RobotError,
    RobotMode,
    RobotState,
    cell_of,
    parse_state,
)
from robot_agent.state_streams import StateStreams
from robot_agent.world import WorldView
from robot_agent.world_feed import WorldFeed


@dataclass
class Entity:
    key: str
    session: Recorder
    puts: list[bytes] = field(default_factory=list)
    live: bool = True

    def put(self, payload: bytes) -> None:
        assert self.live, f"put on undeclared {self.key}"
        self.puts.append(payload)

    def undeclare(self) -> None:
        assert self.live, f"{self.key} undeclared twice"
        self.live = False
        self.session.log.append(("undeclare", self.key))


@dataclass
class Recorder:
    """Records declarations in order (a stand-in for a Zenoh session)."""

    log: list[tuple[str, str]] = field(default_factory=list)
    entities: list[Entity] = field(default_factory=list)

    def _declare(self, key: str) -> Entity:
        entity = Entity(key, self)
        self.entities.append(entity)
        self.log.append(("declare", key))
        return entity

    def declare_publisher(self, key: str) -> Entity:
        return self._declare(key)

    def declare_subscriber(self, key: str, callback: Any, **kwargs: Any) -> Entity:
        return self._declare(key)

    def get(self, *args: Any, **kwargs: Any) -> None:
        return None

    def live_keys(self) -> set[str]:
        return {e.key for e in self.entities if e.live}


KEYS = Keys("t", cell_m=2.0)
PEER_RADIUS = 1.0  # the default: cell size 2 m = twice the peer radius


def state(x: float, y: float, seq: int = 0, **fields: Any) -> RobotState:
    return RobotState(robot_id="r1", seq=seq, stamp=float(seq), pose=Pose(x=x, y=y), **fields)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_the_peer_stream_follows_the_robot_from_cell_to_cell() -> None:
    session = Recorder()
    streams = StateStreams(session, KEYS, "r1", clock=Clock()).open()
    streams.publish(state(0.5, 0.5, 0))
    streams.publish(state(1.9, 0.5, 1))
    streams.publish(state(2.1, 0.5, 2))  # into cell (1, 0)
    peer = [e for e in session.entities if "/cell/" in e.key]
    assert [e.key for e in peer] == ["parkfleet/t/cell/0/0/r1", "parkfleet/t/cell/1/0/r1"]
    assert [len(e.puts) for e in peer] == [2, 1] and not peer[0].live and peer[1].live
    decoded = parse_state(peer[1].puts[0])
    assert isinstance(decoded, RobotState) and decoded.seq == 2
    streams.close()
    assert session.live_keys() == set()


def test_the_fleet_stream_runs_at_its_rate_and_at_once_on_a_change() -> None:
    session, clock = Recorder(), Clock()
    streams = StateStreams(session, KEYS, "r1", fleet_rate_hz=10.0, clock=clock).open()
    fleet = next(e for e in session.entities if e.key == KEYS.state("r1"))
    clock.t += 0.1  # past this robot's phase
    for tick in range(50):  # 1 s at 50 Hz, nothing changing
        streams.publish(state(0.5, 0.5, tick))
        clock.t += 0.02
    assert 9 <= len(fleet.puts) <= 11
    before = len(fleet.puts)
    streams.publish(state(0.5, 0.5, 50, mode=RobotMode.ESTOP))  # not due, but changed
    streams.publish(state(0.5, 0.5, 51, mode=RobotMode.ESTOP))
    streams.publish(
        state(0.5, 0.5, 52, mode=RobotMode.ESTOP,
              errors=[RobotError(code="estop", level="fatal", message="m", since=1.0)])
    )  # fmt: skip
    assert len(fleet.puts) == before + 2
    last = parse_state(fleet.puts[-1])
    assert isinstance(last, RobotState) and last.seq == 52


def test_json_on_the_fleet_stream_for_an_older_service() -> None:
    session = Recorder()
    streams = StateStreams(session, KEYS, "r1", encoding="json", clock=Clock()).open()
    streams.publish(state(0.5, 0.5, 0, mode=RobotMode.DRIVING))
    fleet = next(e for e in session.entities if e.key == KEYS.state("r1"))
    peer = next(e for e in session.entities if "/cell/" in e.key)
    assert fleet.puts[0].startswith(b"{") and peer.puts[0][0] == 1  # peers: compact always


def subscribed_cells(session: Recorder) -> set[tuple[int, int]]:
    out = set()
    for key in session.live_keys():
        parts = key.split("/")
        if parts[2] == "cell":
            out.add((int(parts[3]), int(parts[4])))
    return out


walks = st.lists(
    st.tuples(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4)), min_size=1, max_size=60
)  # steps [m] (a robot at 2 m/s moves 0.04 m a tick: these are big steps)


@settings(max_examples=200)
@given(
    start=st.tuples(st.integers(-6, 6), st.integers(-6, 6)),
    walk=walks,
    peers=st.lists(st.tuples(st.floats(0.0, PEER_RADIUS), st.floats(0.0, 2 * math.pi)), max_size=5),
)
def test_no_peer_within_the_peer_radius_is_outside_the_subscribed_cells(
    start: tuple[int, int], walk: list[tuple[float, float]], peers: list[tuple[float, float]]
) -> None:
    """A robot walking anywhere -- along and across borders and corners (starts on one) --
    is subscribed, after each tick, to the cell of every peer within the peer radius; a
    new cell is declared before an old one goes; never more than its 3 x 3 block."""
    session = Recorder()
    feed = WorldFeed(WorldView(), KEYS)
    feed.attach(session)
    x, y = start[0] * KEYS.cell_m, start[1] * KEYS.cell_m
    for dx, dy in walk:
        x, y = x + dx, y + dy
        session.log.clear()
        feed.follow("r1", x, y)
        after = subscribed_cells(session)
        assert len(after) == 9
        for distance, angle in peers:
            peer = (x + distance * math.cos(angle), y + distance * math.sin(angle))
            assert cell_of(*peer, KEYS.cell_m) in after
        ops = [op for op, _ in session.log]
        assert ops == sorted(ops)  # every "declare" before any "undeclare": no gap
    feed.detach()
    assert session.live_keys() == set()


def test_a_shared_feed_subscribes_to_the_union_once_and_releases_what_nobody_needs() -> None:
    session = Recorder()
    feed = WorldFeed(WorldView(), KEYS)
    feed.follow("a", 0.5, 0.5)  # before attach: remembered, subscribed on attach
    feed.attach(session)
    feed.follow("b", 2.5, 0.5)  # the next cell: blocks overlap in 6 cells
    assert feed.cells == {(cx, cy) for cx in range(-1, 3) for cy in range(-1, 2)}
    cell_keys = [k for op, k in session.log if op == "declare" and "/cell/" in k]
    assert len(cell_keys) == len(set(cell_keys)) == 12
    feed.unfollow("a")
    assert feed.cells == {(cx, cy) for cx in range(0, 3) for cy in range(-1, 2)}
    feed.follow("b", 2.6, 0.5)  # same cell: nothing declared
    assert len(session.entities) == 13  # 12 cells + the obstacles
    feed.detach()
    assert session.live_keys() == set()
