"""Run metrics on time-aligned poses: collisions, separation, deadlocks, arrival, paths."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.bench.metrics import DEADLOCK_WINDOW_S, RunMetrics, RunResult
from fleet.core.wire import Obstacle
from fleet.io.trace import TraceChunk

MODES = ("idle", "driving", "avoiding", "arrived", "holding", "waiting")
DRIVING, ARRIVED, WAITING = 1, 3, 5
DT = 0.02


def _run(
    poses: np.ndarray,
    modes: np.ndarray | None = None,
    goals: list[tuple[float, float, float]] | None = None,
    obstacles: list[Obstacle] | None = None,
    chunk: int = 1000,
) -> RunResult:
    ticks, n = poses.shape[:2]
    if modes is None:
        modes = np.full((ticks, n), DRIVING, dtype=np.uint8)
    goal_rows = goals if goals is not None else [tuple(p) for p in poses[-1]]
    m = RunMetrics([0.2] * n, np.array(goal_rows, dtype=float), obstacles or [], MODES)
    t = np.arange(ticks) * DT
    for a in range(0, ticks, chunk):
        m.add(TraceChunk(t[a : a + chunk], poses[a : a + chunk], modes[a : a + chunk]))
    return m.result()


def _line(
    start: tuple[float, float], end: tuple[float, float], ticks: int, theta: float = 0.0
) -> np.ndarray:
    s = np.linspace(0.0, 1.0, ticks)[:, None]
    xy = np.array(start) + s * (np.array(end) - np.array(start))
    return np.column_stack([xy, np.full(ticks, theta)])


def test_crossing_the_same_point_at_different_instants_is_no_collision() -> None:
    # a passes the origin at t = 1 s, b at t = 3 s: their paths cross, they never meet
    a = _line((-1.0, 0.0), (3.0, 0.0), 201)
    b = _line((0.0, -3.0), (0.0, 1.0), 201, math.pi / 2)
    r = _run(np.stack([a, b], axis=1))
    assert r.collision_pairs == 0 and r.collisions == []
    assert r.min_separation_m is not None and r.min_separation_m > 1.0


def test_meeting_at_the_same_instant_is_a_collision_marked_where_it_began() -> None:
    a = _line((-2.0, 0.0), (2.0, 0.0), 201)
    b = _line((0.0, -2.0), (0.0, 2.0), 201, math.pi / 2)
    r = _run(np.stack([a, b], axis=1), chunk=37)
    assert r.collision_pairs == 1 and r.min_separation_m == pytest.approx(0.0, abs=1e-9)
    (event,) = r.collisions
    assert event.robots == (0, 1) and 1.5 < event.t < 2.0
    assert math.hypot(event.x, event.y) < 0.2


def test_two_contacts_of_one_pair_are_one_colliding_pair_and_two_events() -> None:
    still = np.zeros((300, 3))
    x = np.concatenate(
        [np.linspace(1.0, 0.3, 100), np.linspace(0.3, 1.0, 100), np.linspace(1.0, 0.3, 100)]
    )
    mover = np.column_stack([x, np.zeros(300), np.zeros(300)])
    r = _run(np.stack([still, mover], axis=1))
    assert r.collision_pairs == 1 and len(r.collisions) == 2
    assert r.min_separation_m == pytest.approx(0.3)


def test_a_graze_at_the_sum_of_radii_is_not_a_collision() -> None:
    a = np.zeros((10, 3))
    b = np.tile([0.39995, 0.0, 0.0], (10, 1))  # float32 rounding of a 0.4 m graze
    assert _run(np.stack([a, b], axis=1)).collision_pairs == 0


def test_a_robot_standing_still_far_from_its_goal_is_deadlocked_once() -> None:
    ticks = int(25 / DT)
    stuck = np.zeros((ticks, 1, 3))
    r = _run(stuck, goals=[(5.0, 0.0, 0.0)])
    (event,) = r.deadlocks
    assert event.t == pytest.approx(DEADLOCK_WINDOW_S, abs=DT) and event.robots == (0,)


def test_waiting_on_purpose_idle_or_parking_near_the_goal_is_no_deadlock() -> None:
    ticks = int(25 / DT)
    still = np.zeros((ticks, 1, 3))
    waiting = np.full((ticks, 1), WAITING, dtype=np.uint8)
    assert _run(still, waiting, goals=[(5.0, 0.0, 0.0)]).deadlocks == []
    idle = np.zeros((ticks, 1), dtype=np.uint8)
    assert _run(still, idle, goals=[(5.0, 0.0, 0.0)]).deadlocks == []
    assert _run(still, goals=[(0.3, 0.0, 0.0)]).deadlocks == []  # turning near its goal
    # 8 s waiting then 8 s stuck: the window restarts after the wait
    modes = np.full((int(16 / DT), 1), DRIVING, dtype=np.uint8)
    modes[: int(8 / DT)] = WAITING
    assert _run(np.zeros((len(modes), 1, 3)), modes, goals=[(5.0, 0.0, 0.0)]).deadlocks == []


def test_slow_steady_progress_is_no_deadlock_but_circling_is() -> None:
    ticks = int(40 / DT)
    slow = _line((0.0, 0.0), (4.0, 0.0), ticks)[:, None]  # 0.1 m/s towards the goal
    assert _run(slow, goals=[(5.0, 0.0, 0.0)]).deadlocks == []
    angle = np.linspace(0, 8 * math.pi, ticks)
    circling = np.column_stack([np.cos(angle), np.sin(angle), angle])[:, None]
    assert len(_run(circling, goals=[(5.0, 0.0, 0.0)]).deadlocks) == 1


def test_arrival_makespan_path_ratio_and_obstacle_hits() -> None:
    ticks = 301
    a = _line((0.0, 0.0), (3.0, 0.0), ticks)
    b = _line((0.0, 2.0), (0.0, 2.0), ticks)
    modes = np.full((ticks, 2), DRIVING, dtype=np.uint8)
    modes[290:, 0] = ARRIVED  # 0.1 m short of the goal, within the arrival radius
    r = _run(
        np.stack([a, b], axis=1),
        modes,
        goals=[(3.0, 0.0, 0.0), (np.nan, np.nan, np.nan)],
        obstacles=[Obstacle(x=1.5, y=0.3, radius=1, body=0.15), Obstacle(x=9, y=9, body=0.1)],
    )
    assert r.success_count() == 1 and r.arrivals[0] == pytest.approx(290 * DT)
    assert r.makespan(1, 99.0) == pytest.approx(290 * DT)
    assert r.makespan(2, 99.0) == 99.0  # a task never arrived: the time limit
    # per task that arrived: driven until its arrival (2.9 m) / straight line (3 m); b has none
    assert r.path_ratio() == pytest.approx(2.9 / 3.0)
    never = modes.copy()
    never[:, 0] = DRIVING  # the task never arrives: no path ratio, whatever was driven
    assert (
        _run(np.stack([a, b], axis=1), never, goals=[(3.0, 0.0, 0.0), (np.nan,) * 3]).path_ratio()
        is None
    )
    assert r.obstacle_hits == 1 and r.min_obstacle_clearance_m == pytest.approx(0.3 - 0.35)


@given(
    st.integers(min_value=2, max_value=5),
    st.integers(min_value=1, max_value=300),
    st.integers(min_value=0, max_value=2**31),
)
def test_results_do_not_depend_on_how_ticks_are_chunked(n: int, chunk: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, 0.05, size=(300, n, 3))
    poses = np.cumsum(steps, axis=0) + rng.uniform(-1.0, 1.0, size=(1, n, 3))
    modes = rng.choice([DRIVING, ARRIVED, WAITING], size=(300, n)).astype(np.uint8)
    goals = [tuple(g) for g in rng.uniform(-3, 3, size=(n, 3))]
    whole = _run(poses, modes, goals, chunk=300)
    parts = _run(poses, modes, goals, chunk=chunk)
    assert whole.collision_pairs == parts.collision_pairs
    assert [(e.t, e.robots) for e in whole.collisions] == [
        (e.t, e.robots) for e in parts.collisions
    ]
    assert whole.min_separation_m == pytest.approx(parts.min_separation_m)
    np.testing.assert_allclose(whole.driven, parts.driven)
    np.testing.assert_array_equal(whole.arrivals, parts.arrivals)
    assert [(e.t, e.robots) for e in whole.deadlocks] == [(e.t, e.robots) for e in parts.deadlocks]
    # brute force: the closest pair at any instant
    d = min(
        float(np.hypot(*(poses[:, i, :2] - poses[:, j, :2]).T).min())
        for i in range(n)
        for j in range(i + 1, n)
    )
    assert whole.min_separation_m == pytest.approx(d)


def test_a_robot_serving_two_tasks_completes_both_each_at_its_own_goal() -> None:
    # parks at (2, 0) at t = 2 s, then drives on and parks at (2, 3) at t = 5 s
    first, second = _line((0.0, 0.0), (2.0, 0.0), 101), _line((2.0, 0.0), (2.0, 3.0), 150)
    poses = np.concatenate([first, np.repeat(first[-1:], 50, axis=0), second])[:, None]
    modes = np.full((len(poses), 1), DRIVING, dtype=np.uint8)
    modes[100:150] = ARRIVED
    modes[-1] = ARRIVED
    m = RunMetrics(
        [0.2], [(2.0, 3.0, 0.0)], [], MODES, tasks=[(0, 2.0, 0.0), (0, 2.0, 3.0), (0, -5.0, 0.0)]
    )
    t = np.arange(len(poses)) * DT
    m.add(TraceChunk(t, poses, modes))
    r = m.result()
    assert r.task_arrivals[:2] == pytest.approx([100 * DT, (len(poses) - 1) * DT])
    assert math.isnan(r.task_arrivals[2])  # arrived twice, never there
    assert r.success_count() == 2 and r.makespan(3, 99.0) == 99.0
    assert r.arrivals[0] == pytest.approx(100 * DT)  # the robot's first arrival


def test_arrived_far_from_the_goal_is_no_arrival() -> None:
    poses = _line((0.0, 0.0), (1.0, 0.0), 50)[:, None]
    modes = np.full((50, 1), ARRIVED, dtype=np.uint8)
    assert _run(poses, modes, goals=[(3.0, 0.0, 0.0)]).success_count() == 0


def _trace_of_speeds(segments: list[tuple[float, float, float]]) -> np.ndarray:
    """(ticks, 1, 3) poses of one robot from (duration [s], u [m/s], omega [rad/s]) segments."""
    x = y = theta = 0.0
    poses = [(x, y, theta)]
    for duration, u, omega in segments:
        for _ in range(round(duration / DT)):
            x, y = x + u * math.cos(theta) * DT, y + u * math.sin(theta) * DT
            theta += omega * DT
            poses.append((x, y, theta))
    return np.array(poses)[:, None, :]


@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_stops_and_cusps_of_a_hand_made_trip(chunk: int) -> None:
    poses = _trace_of_speeds(
        [
            (0.4, 0.0, 0.0),  # standing at the start: not a stop
            (1.0, 0.5, 0.0),
            (0.5, 0.0, 1.0),  # a turn in place for 0.5 s: a stop
            (1.0, 0.5, 0.0),
            (0.5, -0.3, 0.0),  # reversing at once: a cusp, no stop
            (0.1, 0.0, 0.0),  # 0.1 s still, shorter than a stop
            (0.5, 0.4, 0.0),  # forward again: a second cusp
            (0.6, 0.0, 0.0),  # the final standstill: not a stop
        ]
    )
    result = _run(poses, chunk=chunk)
    assert (int(result.stops[0]), int(result.cusps[0])) == (1, 2)
    assert result.smoothness(trips=2) == (0.5, 1.0)


def test_a_hold_inside_a_trip_is_a_stop_but_a_new_trip_starts_afresh() -> None:
    poses = _trace_of_speeds([(1.0, 0.5, 0.0), (1.0, 0.0, 0.0), (1.0, -0.5, 0.0)])
    ticks = poses.shape[0]
    held = np.full((ticks, 1), DRIVING, dtype=np.uint8)
    held[50:101] = WAITING  # a planned hold: still the same trip
    assert (int(_run(poses, held).stops[0]), int(_run(poses, held).cusps[0])) == (1, 1)
    parked = held.copy()
    parked[50:101] = ARRIVED  # parked, then a new task: two trips, neither stops nor reverses
    result = _run(poses, parked)
    assert (int(result.stops[0]), int(result.cusps[0])) == (0, 0)
