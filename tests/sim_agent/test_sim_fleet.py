"""Spawn layouts and a lockstep fleet without Zenoh (agents share one world view)."""

from __future__ import annotations

import json
import math
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

from fleet.core.params import Gains, Tolerance
from fleet.core.simulate import BatchProblem, batch_filter, simulate
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
    settings = load_settings(avoidance={"k_avoid": 0.0}, safety={"enabled": False})
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


def test_a_lockstep_fleet_among_peers_is_the_batch_simulation_of_the_same_scene() -> None:
    """Agents on simulated drives, ticked in two phases (all sense at t, then all act), follow
    the batch simulator step for step: the same compiled control step, peers read at the
    same time t. The moving robots a, c and d pass within each other's influence radius;
    a weak repulsion lets a reach the idle robot b next to its goal, where only the safety
    filter holds it off. The filter sees every peer exactly (no latency, link or pose error
    in this scene), as the batch does: each agent predicts its pose zero seconds ahead and
    sees its peers at their fresh readings; no speed-up is capped (the batch has no
    acceleration limit)."""
    exact = {
        "pose_error_m": 0.0,
        "heading_error_rad": 0.0,
        "max_latency_s": 0.0,
        "link_delay_s": 0.0,
        "max_accel_m_s2": 100.0,
        "prediction": True,
    }
    settings = load_settings(avoidance={"k_avoid": 0.05}, safety=exact)
    avoid, period = settings.avoidance, 1.0 / settings.control_rate_hz
    spawns = [
        Spawn("a", -2.0, -1.0, 0.0),
        Spawn("b", 0.0, 0.0, 0.0),  # idle: stands in a's way
        Spawn("c", 2.0, -0.5, math.pi),
        Spawn("d", 1.0, -2.0, math.pi / 2),
    ]
    goals = {"a": (0.2, -0.4, 0.0), "c": (-1.0, 1.5, math.pi), "d": (1.0, 2.0, math.pi / 2)}
    laws = {"a": "cw", "c": "cw", "d": "cw"}
    fleet = SimFleet(None, settings, spawns)
    for rid, goal in goals.items():
        fleet.agent(rid).submit(_park(rid, goal).model_copy(update={"law": laws[rid]}))
    ticks = 2500  # 50 s: c arrives (42.5 s), a stays held off b by the filter
    poses, modes, controls = [], [], []
    for _ in range(ticks):
        fleet.tick()
        poses.append([a.last.pose.as_tuple() if a.last else (0, 0, 0) for a in fleet.agents])
        modes.append([a.last.mode if a.last else None for a in fleet.agents])
        controls.append([(a.last.decision.u, a.last.decision.omega) if a.last else (0, 0)
                         for a in fleet.agents])  # fmt: skip

    still = Tolerance(position=1e-9, heading=1e-9)  # b: a row that is done from the start
    problem = BatchProblem.build(
        [(s.x, s.y, s.theta) for s in spawns],
        [goals.get(s.robot_id, (s.x, s.y, s.theta)) for s in spawns],
        Gains(kx=1, ky=2, ktheta=1),
        [laws.get(s.robot_id, "ccw") for s in spawns],
        [still if s.robot_id == "b" else TOL for s in spawns],
        settings.profile,
        k_avoid=avoid.k_avoid,
        peer_radius=avoid.peer_radius,
        min_x_oa=avoid.min_x_oa,
        smoothing=avoid.smoothing_m,
        safety=batch_filter(settings.safety),
    )
    batch = simulate(problem, dt=period, max_time=ticks * period, record=True)
    assert batch.trajectory is not None
    np.testing.assert_allclose(np.array(poses), batch.trajectory.poses[:ticks], rtol=0, atol=1e-9)
    # arrivals on the same tick: the stop rule's step k is reported at tick k
    for i, rid in enumerate(s.robot_id for s in spawns):
        if rid == "b":
            continue  # idle: a row done from the start, an agent without a task
        arrived = [k for k, m in enumerate(modes) if m[i] is RobotMode.ARRIVED]
        assert bool(arrived) == bool(batch.done[i])
        if arrived:
            assert arrived[0] == round(batch.time[i] / period) - 1
        if rid == "a":
            assert not batch.done[i]
        if rid == "c":
            assert batch.done[i]
    # the filter acted: a is held off b by the margin, never closer
    a, b = np.array(poses)[:, 0, :2], np.array(poses)[:, 1, :2]
    gap = np.hypot(*(a - b).T)
    margin = 2 * settings.profile.radius + settings.safety.contact_margin_m
    assert gap.min() >= margin - 1e-9
    near = [k for k in range(ticks) if gap[k] < margin + 0.1]
    assert near and any(modes[k][0] is RobotMode.AVOIDING for k in near)
    # moving peers interacted (a one-phase tick, reading some peers a period late, diverges)
    c, d = np.array(poses)[:, 2, :2], np.array(poses)[:, 3, :2]
    assert np.hypot(*(c - d).T).min() < avoid.peer_radius
    assert all(agent.tick_errors == 0 for agent in fleet.agents)
