"""``parkfleet bench zenoh``: the light state stream and the spawn speak the agents' wire."""

from __future__ import annotations

import math

import pytest

from fleet.bench.state_stream import frames, payload
from fleet.bench.zenoh import spread_spawn
from fleet.core.wire import Keys, RobotState, parse_state


@pytest.mark.parametrize(("seq", "stamp"), [(0, 0.0), (12, 1_764_000_000.123456), (10**9, 5e-3)])
def test_stream_payloads_are_the_agents_compact_states_on_their_cells(
    seq: int, stamp: float
) -> None:
    keys = Keys("f")
    spawn = spread_spawn(30, area_per_robot_m2=10.0, seed=1)
    rendered = frames(keys, spawn)
    assert len({peer for peer, _, _ in rendered}) == 30
    for entry, (peer, fleet, frame) in zip(spawn, rendered, strict=True):
        state = parse_state(payload(frame, seq, stamp))
        assert isinstance(state, RobotState)
        assert (state.robot_id, state.seq, state.stamp) == (entry["id"], seq, stamp)
        assert keys.robot_of(peer) == keys.robot_of(fleet) == state.robot_id
        assert peer == keys.peer_state(state.robot_id, keys.cell(state.pose.x, state.pose.y))


def test_the_spread_spawn_has_the_density_asked_and_keeps_bodies_apart() -> None:
    spawn = spread_spawn(200, area_per_robot_m2=10.0, seed=0)
    xs, ys = [float(e["x"]) for e in spawn], [float(e["y"]) for e in spawn]
    side = math.sqrt(200 * 10.0)
    assert max(xs) - min(xs) <= side and max(ys) - min(ys) <= side
    assert len({e["id"] for e in spawn}) == 200
    closest = min(math.hypot(xs[i] - xs[j], ys[i] - ys[j]) for i in range(200) for j in range(i))
    assert closest >= 0.5
