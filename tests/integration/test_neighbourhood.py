"""Neighbourhood keys on real Zenoh over loopback: a robot walking across cell borders and
corners hears every peer within the peer radius on every tick, and never a far one."""

from __future__ import annotations

import math

import pytest
from support import StateWatcher, wait_for

from fleet.core.wire import Pose, RobotState
from fleet.io.settings import Settings
from fleet.io.transport import open_session
from robot_agent.state_streams import StateStreams
from robot_agent.world import WorldView
from robot_agent.world_feed import WorldFeed

pytestmark = pytest.mark.integration


def _state(robot_id: str, seq: int, x: float, y: float) -> RobotState:
    return RobotState(robot_id=robot_id, seq=seq, stamp=float(seq), pose=Pose(x=x, y=y))


def test_a_walking_robot_hears_every_near_peer_every_tick_and_no_far_one(
    client_settings: Settings,
) -> None:
    keys = client_settings.keys()
    peer_radius = client_settings.avoidance.peer_radius
    assert keys.cell_m == 2 * peer_radius
    # From (-4.9, -4.1) to (4.9, 4.1) in 0.25 m steps, then along the border y = 0: the
    # walk crosses cell borders and passes through the corner (0, 0).
    path = [(-4.9 + 0.25 * k, -4.1 + 0.21 * k) for k in range(40)]
    path += [(4.9 - 0.25 * k, 0.0) for k in range(40)]
    with (
        open_session(client_settings, "client") as robot,
        open_session(client_settings, "client") as peers,
    ):
        feed = WorldFeed(WorldView(), keys)
        feed.attach(robot)
        watcher = StateWatcher(peers, keys)  # the fleet-rate stream, as the service reads it
        near = StateStreams(peers, keys, "near", fleet_rate_hz=1000.0).open()
        far = StateStreams(peers, keys, "far").open()
        try:
            x, y = path[0]
            feed.follow("me", x, y)

            def heard_first() -> bool:  # until the first subscriptions reach the router
                near.publish(_state("near", 0, x + 0.5, y))
                return "near" in feed.world.states()

            wait_for(heard_first, 10, "the first peer state", poll=0.05)
            for seq, (x, y) in enumerate(path[1:], start=1):
                feed.follow("me", x, y)
                angle = 0.7 * seq
                # far: 7 m away (beyond the 3 x 3 block); near: within the peer radius,
                # on whichever side of a border that puts it
                far.publish(_state("far", seq, x + 7.0, y - 7.0))
                distance = peer_radius * (0.3 + 0.7 * (seq % 7) / 6)
                nx, ny = x + distance * math.cos(angle), y + distance * math.sin(angle)
                near.publish(_state("near", seq, nx, ny))

                def heard(seq: int = seq) -> bool:
                    state = feed.world.states().get("near")
                    return state is not None and state.seq >= seq

                # one put each: a near peer is never on a cell only just subscribed
                wait_for(heard, 10, f"near peer's state {seq} at distance {distance:.2f} m")
            assert "far" not in feed.world.states()
            assert feed.decoder.dropped_total == 0
            assert feed.resubscriptions > 10  # it really moved over many cells
            wait_for(lambda: watcher.latest("far") is not None, 10, "the fleet-rate stream")
        finally:
            watcher.close()
            near.close()
            far.close()
            feed.detach()
