"""Neighbourhood keys on real Zenoh over loopback: a robot walking across cell borders and
corners hears every peer within the peer radius on every tick, and never a far one; a
robot entering a cell learns of a silent robot there from the service."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from support import StateWatcher, wait_for, zenoh_fleet_service

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


def test_a_robot_entering_a_cell_learns_of_a_silent_robot_there_from_the_service(
    client_settings: Settings, tmp_path: Path
) -> None:
    """A robot that died publishes nothing a newcomer could hear: the service replays its
    last state, with its age, to a robot that subscribes to its cell -- and only then."""
    keys = client_settings.keys()
    safety = client_settings.safety
    with (
        zenoh_fleet_service(client_settings, tmp_path / "fleet.db") as service,
        open_session(client_settings, "client") as robot,
        open_session(client_settings, "client") as peers,
    ):
        dead = StateStreams(peers, keys, "dead").open()
        dead_state = RobotState(
            robot_id="dead", seq=1, stamp=time.time(), pose=Pose(x=-0.5, y=0.3), u=0.4
        )

        def known() -> bool:
            dead.publish(dead_state)
            return "dead" in {r.robot_id for r in service.robots()}

        wait_for(known, 10, "the service to hear the robot", poll=0.05)
        dead.close()  # it dies: nothing more on either stream
        wait_for(
            lambda: any(age >= 1.0 for _, age in service.last_states()), 10, "a second of silence"
        )
        feed = WorldFeed(WorldView(), keys)
        feed.attach(robot)
        try:
            feed.follow("me", 6.5, 0.5)  # three cells away: its block does not hold the cell
            wait_for(lambda: len(feed.cells) == 9, 10, "the first block")
            assert "dead" not in feed.world.states()
            feed.follow("me", 1.5, 0.5)  # the next cell but one: now it does
            wait_for(lambda: "dead" in feed.world.states(), 10, "the replayed robot")
            assert feed.world.states()["dead"].pose == dead_state.pose
            _, shapes = feed.world.peer_bodies("me", safety, 0.2)
            # heard (by the service) at least a second ago, not just now
            assert shapes[1, 0] >= safety.peer_spread(0.4, 1.0)
            assert feed.decoder.dropped_total == 0
        finally:
            feed.detach()


def test_a_robot_silent_only_a_moment_is_replayed_too(
    client_settings: Settings, tmp_path: Path
) -> None:
    """The race of a SIGKILLed robot: a newcomer entering its cell just after its last
    message (before any silence threshold) would hear nothing, ever. The service replays
    every robot it knows there, and the feed keeps the newest state by ``seq``."""
    keys = client_settings.keys()
    with (
        zenoh_fleet_service(client_settings, tmp_path / "fleet.db") as service,
        open_session(client_settings, "client") as robot,
        open_session(client_settings, "client") as peers,
    ):
        quiet = StateStreams(peers, keys, "quiet").open()
        try:
            last = RobotState(robot_id="quiet", seq=7, stamp=time.time(), pose=Pose(x=0.5, y=0.3))

            def known() -> bool:
                quiet.publish(last)
                return "quiet" in {r.robot_id for r in service.robots()}

            wait_for(known, 10, "the service to hear the robot's last message", poll=0.05)
            feed = WorldFeed(WorldView(), keys)
            feed.attach(robot)
            try:
                feed.follow("me", 1.5, 0.5)  # at once: the robot fell silent just now
                wait_for(lambda: "quiet" in feed.world.states(), 10, "the replayed robot")
                assert feed.world.states()["quiet"] == last
                assert feed.decoder.dropped_total == 0
            finally:
                feed.detach()
        finally:
            quiet.close()
