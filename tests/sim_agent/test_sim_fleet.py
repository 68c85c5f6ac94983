"""Spawn layouts and a lockstep fleet without Zenoh (agents share one world view)."""

from __future__ import annotations

import json
import math
from itertools import combinations
from pathlib import Path

import pytest

from fleet.core.params import Gains, Tolerance
from fleet.core.wire import ParkAssignment, Pose, RobotMode
from fleet.io.settings import load_settings
from sim_agent.fleet import SimFleet, Spawn, spawn_layout

TOL = Tolerance(position=0.1, heading=0.1)


def test_grid_layout_ids_and_spacing() -> None:
    spawns = spawn_layout("grid", 10, id_prefix="robot-")
    assert [s.robot_id for s in spawns] == [f"robot-{i}" for i in range(1, 11)]
    dists = [math.hypot(a.x - b.x, a.y - b.y) for a, b in combinations(spawns, 2)]
    assert min(dists) == pytest.approx(1.5)


def test_random_layout_is_seeded_separated_and_inside_the_yard() -> None:
    a = spawn_layout("random", 30, seed=7)
    assert a == spawn_layout("random", 30, seed=7)
    assert a != spawn_layout("random", 30, seed=8)
    assert all(-10 <= s.x <= 10 and -10 <= s.y <= 10 for s in a)
    assert min(math.hypot(p.x - q.x, p.y - q.y) for p, q in combinations(a, 2)) >= 1.5


def test_file_layout(tmp_path: Path) -> None:
    f = tmp_path / "spawn.json"
    f.write_text(
        json.dumps([{"id": "a1", "x": 1, "y": 2, "theta": 0.5}, {"id": "b", "x": 0, "y": 0}])
    )
    assert spawn_layout(str(f), 99) == [Spawn("a1", 1, 2, 0.5), Spawn("b", 0, 0, 0)]
    f.write_text(json.dumps([{"id": "bad/id", "x": 1, "y": 2}]))
    with pytest.raises(ValueError, match="invalid robot id"):
        spawn_layout(str(f), 1)
    with pytest.raises(FileNotFoundError):
        spawn_layout(str(tmp_path / "missing.json"), 1)


def _park(rid: str, goal: tuple[float, float, float]) -> ParkAssignment:
    return ParkAssignment(
        robot_id=rid, task_id=f"t-{rid}", goal=Pose(x=goal[0], y=goal[1], theta=goal[2]),
        law="ccw", gains=Gains(kx=1, ky=2, ktheta=1), tolerance=TOL,
    )  # fmt: skip


def test_crossing_robots_keep_apart_in_lockstep_without_zenoh() -> None:
    settings = load_settings()
    spawns = [Spawn("a", -3.0, 0.0, 0.0), Spawn("b", 0.0, -3.0, math.pi / 2)]
    fleet = SimFleet(None, settings, spawns)
    fleet.agent("a").submit(_park("a", (3.0, 0.0, 0.0)))
    fleet.agent("b").submit(_park("b", (0.0, 3.0, math.pi / 2)))
    closest = math.inf
    modes = set()
    for _ in range(1500):  # 30 s of simulated time at 50 Hz
        fleet.tick()
        (ax, ay, _), (bx, by, _) = fleet.drives["a"].true_pose, fleet.drives["b"].true_pose
        closest = min(closest, math.hypot(ax - bx, ay - by))
        modes |= {agent.last.mode for agent in fleet.agents if agent.last}
    assert RobotMode.AVOIDING in modes
    assert closest > 2 * settings.profile.radius
    # both really moved towards the crossing (standing still would pass trivially)
    assert fleet.drives["a"].true_pose[0] > -2.0 and fleet.drives["b"].true_pose[1] > -2.0
    assert all(a.tick_errors == 0 for a in fleet.agents)


def test_without_avoidance_the_same_crossing_collides() -> None:
    settings = load_settings(avoidance={"k_avoid": 0.0})
    spawns = [Spawn("a", -3.0, 0.0, 0.0), Spawn("b", 0.0, -3.0, math.pi / 2)]
    fleet = SimFleet(None, settings, spawns)
    fleet.agent("a").submit(
        _park("a", (3.0, 0.0, 0.0)).model_copy(update={"avoidance": settings.avoidance})
    )
    fleet.agent("b").submit(
        _park("b", (0.0, 3.0, math.pi / 2)).model_copy(update={"avoidance": settings.avoidance})
    )
    closest = math.inf
    for _ in range(1500):
        fleet.tick()
        (ax, ay, _), (bx, by, _) = fleet.drives["a"].true_pose, fleet.drives["b"].true_pose
        closest = min(closest, math.hypot(ax - bx, ay - by))
    assert closest < 2 * settings.profile.radius
