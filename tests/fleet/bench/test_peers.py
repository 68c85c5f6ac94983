"""navground peers on benchmark scenarios: pose targets, arrivals, the goal assignment."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.bench.metrics import RunMetrics
from fleet.bench.peers import MODES, PeerRun, assign_goals, goals_by_robot, run_peer
from fleet.bench.scenarios import RobotSpec, Scenario, swap
from fleet.core.params import RobotProfile
from fleet.io.trace import TraceChunk
from sim_agent.disturbances import Disturbances, LinkDisturbances
from sim_agent.robots import SimRobots

pytest.importorskip("navground")


def _ticks(scenario: Scenario, behaviour: str, robots: SimRobots | None = None) -> TraceChunk:
    run = PeerRun(behaviour, RobotProfile(), robots=robots or SimRobots())
    chunks = list(run_peer(scenario, run))
    return TraceChunk(
        np.concatenate([c.t for c in chunks]),
        np.concatenate([c.poses for c in chunks]),
        np.concatenate([c.modes for c in chunks]),
    )


@pytest.mark.parametrize("behaviour", ["orca", "hrvo", "hl", "socialforce"])
def test_a_two_robot_swap_ends_in_both_goal_poses(behaviour: str) -> None:
    scenario = swap(2, "left")
    ticks = _ticks(scenario, behaviour)
    arrived = MODES.index("arrived")
    assert (ticks.modes[-1] == arrived).all() and ticks.t[-1] < scenario.end_s
    for pose, goal in zip(ticks.poses[-1], scenario.goals, strict=True):
        assert math.dist(pose[:2], goal[:2]) < scenario.tolerance.position + 0.02
        heading = abs(math.remainder(pose[2] - goal[2], 2 * math.pi))
        assert heading < scenario.tolerance.heading + 0.02  # a pose, not just a position
    metrics = RunMetrics([0.2, 0.2], np.array(scenario.goals), [], MODES)
    metrics.add(ticks)
    assert metrics.result().success_count() == 2


def test_hl_leaves_a_symmetric_ring_and_runs_are_seeded() -> None:
    scenario = swap(4, "right")
    a, b = _ticks(scenario, "hl"), _ticks(scenario, "hl")
    np.testing.assert_array_equal(a.poses, b.poses)
    assert (a.modes[-1] == MODES.index("arrived")).all()


def test_a_late_task_leaves_its_robot_idle_until_it_arrives() -> None:
    scenario = Scenario(
        name="late",
        robots=[
            RobotSpec(start=(0, 0, 0), goal=(2, 0, 0)),
            RobotSpec(start=(0, 3, 0), goal=(2, 3, 0), arrival_s=4.0),
        ],
    )
    ticks = _ticks(scenario, "orca")
    before = ticks.t < 4.0 - 1e-9
    assert (ticks.modes[before, 1] == MODES.index("idle")).all()
    np.testing.assert_allclose(ticks.poses[before, 1, 1], ticks.poses[0, 1, 1])
    assert ticks.modes[-1, 1] == MODES.index("arrived")
    with pytest.raises(ValueError, match="unknown navground behaviour"):
        next(run_peer(scenario, PeerRun("astar", RobotProfile(), robots=SimRobots())))
    with pytest.raises(ValueError, match="needs robots"):
        next(run_peer(scenario, PeerRun("orca", RobotProfile())))


def _first_motion(ticks: TraceChunk, robot: int = 0) -> float:
    moved = np.hypot(*(ticks.poses[:, robot, :2] - ticks.poses[0, robot, :2]).T) > 1e-9
    return float(ticks.t[int(np.argmax(moved))])


def test_the_peers_drive_the_benchmark_robots_with_their_latency_and_seeded_noise() -> None:
    scenario = swap(2, "left")
    perfect = _ticks(scenario, "orca")
    late = SimRobots(Disturbances(latency_s=(0.1, 0.1)))
    delayed = _ticks(scenario, "orca", late)
    # the first command reaches the wheels 0.1 s after it is sent (plus the tick it was sent)
    assert _first_motion(delayed) == pytest.approx(_first_motion(perfect) + 0.1, abs=0.021)
    noisy = SimRobots.realistic()
    a, b = _ticks(scenario, "orca", noisy), _ticks(scenario, "orca", noisy)
    np.testing.assert_array_equal(a.poses, b.poses)  # seeded: the same robots every run
    assert (a.modes[-1] == MODES.index("arrived")).all()
    assert not np.array_equal(a.poses[: len(perfect.t)], perfect.poses[: len(a.t)])


def test_on_a_dead_link_the_peers_never_see_each_other() -> None:
    scenario = swap(2, "left")
    blind = _ticks(scenario, "orca", SimRobots(link=LinkDisturbances(loss=0.999999)))
    seeing = _ticks(scenario, "orca", SimRobots(link=LinkDisturbances(delay_s=(0.02, 0.02))))
    closest = [
        float(np.min(np.hypot(*(t.poses[:, 0, :2] - t.poses[:, 1, :2]).T))) for t in (blind, seeing)
    ]
    assert closest[0] < 0.4 < closest[1]  # blind robots drive into each other; seeing ones pass


@given(st.integers(2, 5), st.integers(0, 2**31), st.booleans())
def test_the_assignment_is_optimal_per_arrival_group(n: int, seed: int, staggered: bool) -> None:
    rng = np.random.default_rng(seed)
    points = [(float(x), -9.0 + 3.0 * k, 0.0) for k, x in enumerate(rng.uniform(-8, 8, size=n))]
    goals = [(float(x), -8.5 + 3.0 * k, 0.0) for k, x in enumerate(rng.uniform(-8, 8, size=n))]
    arrivals = [0.0] * n if not staggered else [0.0] + [5.0] * (n - 1)
    scenario = Scenario(
        name="a",
        named=False,
        robots=[
            RobotSpec(start=s, goal=g, arrival_s=t)
            for s, g, t in zip(points, goals, arrivals, strict=True)
        ],
    )
    owner = assign_goals(scenario)
    assert sorted(owner) == list(range(n))
    cost = np.hypot(
        *(np.array(points)[:, None, :2] - np.array(goals)[None, :, :2]).transpose(2, 0, 1)
    )
    if not staggered:
        best = min(sum(cost[p[k], k] for k in range(n)) for p in itertools.permutations(range(n)))
        assert sum(cost[owner[k], k] for k in range(n)) == pytest.approx(best)
    else:  # the first task goes to the nearest robot, the rest to the others
        assert owner[0] == int(np.argmin(cost[:, 0]))
    placed = goals_by_robot(scenario, owner)
    for task, robot in enumerate(owner):
        assert tuple(placed[robot]) == goals[task]


@pytest.mark.parametrize("behaviour", ["orca", "hrvo", "hl", "socialforce"])
def test_a_wall_between_start_and_goal_is_not_driven_through(behaviour: str) -> None:
    """Every peer sees a wall (navground's HRVO reads only discs: the wall's disc chain);
    none of them crosses it, whether it finds the way round or not."""
    from fleet.core.site import Wall

    scenario = Scenario(
        name="wall",
        robots=[RobotSpec(start=(-3, 0, 0), goal=(3, 0, 0))],
        walls=[Wall(points=[(0.0, -1.5), (0.0, 1.5)], body=0.1)],
        time_limit_s=40.0,
    )
    ticks = _ticks(scenario, behaviour)
    metrics = RunMetrics([0.2], np.array(scenario.goals), scenario.static_obstacles(), MODES)
    metrics.add(ticks)
    assert metrics.result().obstacle_hits == 0
    xy = ticks.poses[:, 0, :2]
    crossed = np.nonzero(xy[:, 0] > 0.0)[0]
    assert crossed.size == 0 or (np.abs(xy[crossed[0], 1]) > 1.5).all()  # round the end
