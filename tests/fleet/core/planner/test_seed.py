"""The prioritised seed staggers robots whose solo paths cross at the same time, and the
cost counts a pair that starts close only if it gets closer."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from planning import idle, queued, scene

from fleet.core.planner import PlannerConfig, PlanningSnapshot
from fleet.core.planner.assign import pair_queued
from fleet.core.planner.cost import Limits
from fleet.core.planner.reserve import reservation
from fleet.core.planner.rollout import Rows
from fleet.core.planner.scene import build_fleet


def test_the_seed_makes_one_of_two_crossing_robots_wait() -> None:
    snapshot = scene(
        [(-4.0, 0.0, 0.0), (0.0, -4.0, math.pi / 2)],
        [(4.0, 0.0, 0.0), (0.0, 4.0, math.pi / 2)],
        direction="cw",
    )
    config = PlannerConfig()
    fleet = build_fleet(snapshot, pair_queued(snapshot, config), config)
    seed, paths = reservation(fleet, [0, 1], [], config.reserve_delays_s, 1.0, 0.75)
    assert sorted(seed.delay > 0) == [False, True] and not seed.hold.any()
    gap = np.hypot(*(paths[0] - paths[1]).T)
    assert gap.min() >= 1.0  # the staggered solo paths never come within reach


def test_the_seed_does_not_delay_a_robot_whose_way_a_standing_robot_blocks() -> None:
    """Waiting does not move a standing robot out of the way: the seed starts the robot at
    once (the search and the filter take it round), not with the longest delay there is,
    which only postpones the conflict furthest (on the fleet benchmark a robot stood 20 s
    behind a parked one that way). The parked robot stands beside the goal, too near it for
    a route round it (one dead ahead further off is gone round)."""
    snapshot = PlanningSnapshot(
        version=1,
        robots=(idle("r0", (-4.0, 0.0, 0.0)), idle("r1", (3.3, 0.1, 0.0))),
        tasks=(queued("t0", (4.0, 0.0, 0.0), "r0"),),
        separation_m=0.5,
        control_dt=0.05,
    )
    config = PlannerConfig()
    fleet = build_fleet(snapshot, pair_queued(snapshot, config), config)
    seed, paths = reservation(fleet, [0], [0], config.reserve_delays_s, 1.0, 0.75)
    assert np.hypot(*(paths[0] - [3.3, 0.1]).T).min() < 0.75  # no option is clear of it
    assert seed.delay.tolist() == [0.0] and not seed.hold.any()


def test_a_pair_that_starts_close_may_not_get_closer() -> None:
    rows = Rows.standing(np.array([[0.0, 0.0], [0.3, 0.0], [5.0, 0.0]]))
    limits = Limits.of(0.5, rows, np.array([True, False, False]))
    assert limits.allowed[0, 1] < 0.3 and limits.allowed[0, 2] == 0.5
    assert not limits.involved[1, 2]  # two standing robots: nobody's business
    closest = np.array([[np.inf, 0.3, 4.0], [0.3, np.inf, 0.1], [4.0, 0.1, np.inf]])
    assert not limits.broken(closest)
    closest[0, 1] = closest[1, 0] = 0.29
    assert limits.broken(closest)


def test_a_robot_that_must_pass_a_goal_is_placed_before_its_owner_parks() -> None:
    from fleet.core.planner.gates import blocked_first

    blocks = np.zeros((3, 3), dtype=bool)
    blocks[2, 0] = True  # robot 2's every way passes robot 0's goal
    assert blocked_first([0, 1, 2], blocks) == [2, 0, 1]
    blocks[0, 2] = True  # a cycle keeps the preferred order as far as it can
    assert sorted(blocked_first([0, 1, 2], blocks)) == [0, 1, 2]


def test_holding_a_robot_that_another_will_park_in_front_of_is_a_trap() -> None:
    from fleet.core.planner.cost import trapped

    snapshot = scene(
        [(-4.0, 0.0, 0.0), (6.0, 3.0, -math.pi / 2)],
        [(4.0, 0.0, 0.0), (0.0, 0.1, math.pi)],  # robot 1 parks on robot 0's way
        direction="cw",
    )
    config = PlannerConfig()
    fleet = build_fleet(snapshot, pair_queued(snapshot, config), config)
    assert fleet.blocks[0, 1] and not fleet.blocks[1, 0]
    keep = fleet.keep([0, 1])
    held_0 = replace(keep, hold=np.array([True, False]))
    held_1 = replace(keep, hold=np.array([False, True]))
    assert trapped(fleet, [0, 1], held_0) == 1 and trapped(fleet, [0, 1], held_1) == 0


def test_unnamed_tasks_avoid_robots_whose_way_a_lost_robot_blocks() -> None:
    from planning import idle, queued

    from fleet.core.planner.model import PlanningSnapshot, RobotSnapshot
    from fleet.core.tasks import RobotStatus

    robots = (
        idle("blocked", (-3.0, 0.0, 0.0)),
        idle("free", (3.0, 0.2, math.pi)),
        RobotSnapshot("lost", (-1.5, 0.0, 0.0), RobotStatus.LOST, available=False),
    )
    tasks = (queued("t", (0.0, 0.0, 0.0), None),)
    pairs = pair_queued(PlanningSnapshot(1, robots, tasks), PlannerConfig())
    assert [(t.task_id, r.robot_id) for t, r in pairs] == [("t", "free")]
