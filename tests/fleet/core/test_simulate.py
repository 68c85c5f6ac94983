"""Closed-loop behaviour of the batch simulator and the paper's experiments."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fleet.core import step
from fleet.core.control import lyapunov_p, lyapunov_v, wheel_speeds
from fleet.core.params import Gains, RobotProfile, Tolerance
from fleet.core.simulate import BatchProblem, simulate, warm_parallel_kernel
from fleet.paper.reproduce import run_scenario
from fleet.paper.scenarios import SCENARIOS

posture = st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-math.pi, math.pi))
gains_st = st.builds(Gains, kx=st.floats(0.5, 5), ky=st.floats(0.5, 10), ktheta=st.floats(0.5, 15))


@settings(max_examples=40, deadline=None)
@given(posture, posture, gains_st, st.sampled_from(["ccw", "cw"]))
def test_lyapunov_function_does_not_increase_between_heading_wraps(
    start: tuple[float, ...], goal: tuple[float, ...], gains: Gains, law: str
) -> None:
    """V (12.a) for ccw and P (22) for cw decrease along the loop, except at wraps (11.b)/(21).

    Forward Euler adds an O(dt^2) error per step, so a small dt is used and the
    allowance is second order.
    """
    dt = 1e-3
    problem = BatchProblem.build(start, goal, gains, law, Tolerance(position=0.05, heading=0.05))
    result = simulate(problem, dt=dt, max_time=4.0, record=True)
    assert result.trajectory is not None
    e = result.trajectory.errors[:, 0, :]
    fn = lyapunov_v if law == "ccw" else lyapunov_p
    values = fn(e[:, 0], e[:, 1], e[:, 2])
    wrapped = np.abs(np.diff(e[:, 2])) > math.pi
    increase = np.diff(values)[~wrapped]
    allowance = 1e-3 * np.maximum(values[:-1][~wrapped], 1.0)
    assert (increase <= allowance).all(), float(increase.max())


@settings(max_examples=25, deadline=None)
@given(posture, posture, st.sampled_from(["ccw", "cw"]))
def test_robot_reaches_tolerance_from_random_postures_within_bounded_time(
    start: tuple[float, ...], goal: tuple[float, ...], law: str
) -> None:
    gains = SCENARIOS["II"].gains[law]  # the paper's comparative case II gains
    tol = Tolerance(position=0.1, heading=0.1)
    result = simulate(BatchProblem.build(start, goal, gains, law, tol), max_time=120.0)
    assert result.done[0], f"did not arrive; final pose {result.final_pose[0]}"
    assert result.time[0] <= 120.0
    x_e = goal[0] - result.final_pose[0, 0]
    y_e = goal[1] - result.final_pose[0, 1]
    # The final applied step may move the robot slightly past the pre-step check.
    assert math.hypot(x_e, y_e) < 0.1 + 0.01 * 20


def test_stop_rule_counts_the_step_that_is_already_inside_tolerance() -> None:
    # Starting exactly on the goal: step 0 is inside tolerance, still applied: time = dt.
    result = simulate(
        BatchProblem.build((1.0, 2.0, 0.3), (1.0, 2.0, 0.3), Gains(kx=1, ky=1, ktheta=1), "ccw")
    )
    assert result.done[0] and result.time[0] == pytest.approx(0.01)
    assert result.control_effort[0] == 0.0 and result.steps == 1


def test_batch_robots_are_independent_without_avoidance() -> None:
    starts = [SCENARIOS[c].start for c in ("I", "II", "III")]
    goals = [SCENARIOS[c].goal for c in ("I", "II", "III")]
    gains = [SCENARIOS[c].gains["cw"] for c in ("I", "II", "III")]
    tols = [SCENARIOS[c].tolerance for c in ("I", "II", "III")]
    batch = simulate(BatchProblem.build(starts, goals, gains, "cw", tols), max_time=120)
    for i, case in enumerate(("I", "II", "III")):
        alone = run_scenario(SCENARIOS[case], "cw")
        assert batch.time[i] == alone.time[0]
        assert batch.control_effort[i] == pytest.approx(alone.control_effort[0], rel=1e-12)


def test_wheel_limit_slows_the_robot_but_keeps_it_converging() -> None:
    sc = SCENARIOS["II"]
    limited = RobotProfile(wheel_radius=0.05, half_axle=0.135, max_wheel_speed=20.0)
    free = run_scenario(sc, "ccw", record=True)
    slow = simulate(
        BatchProblem.build(sc.start, sc.goal, sc.gains["ccw"], "ccw", sc.tolerance, limited),
        max_time=300,
        record=True,
    )
    assert slow.done[0] and slow.time[0] > free.time[0]
    assert slow.trajectory is not None
    right, left = slow.trajectory.wheel_speeds(0.05, 0.135)
    assert np.abs(right).max() <= 20.0 + 1e-9 and np.abs(left).max() <= 20.0 + 1e-9


def test_static_obstacles_repel_the_robot_in_the_paper_two_obstacle_case() -> None:
    """Section 6: case III with law (20), K_avoid = 4, influence radius 1 m."""
    sc = SCENARIOS["III"]
    obstacles = [(-0.6, 0.0), (0.9, 0.3)]
    free = run_scenario(sc, "cw", record=True)
    problem = BatchProblem.build(
        sc.start, sc.goal, sc.gains["cw"], "cw", sc.tolerance, obstacles=obstacles, k_avoid=4.0
    )
    avoided = simulate(problem, max_time=120, record=True)
    assert avoided.done[0]
    assert free.trajectory is not None and avoided.trajectory is not None

    def clearance(poses: np.ndarray) -> float:
        return float(
            min(np.hypot(poses[:, 0, 0] - ox, poses[:, 0, 1] - oy).min() for ox, oy in obstacles)
        )

    assert clearance(avoided.trajectory.poses) > clearance(free.trajectory.poses)


def test_peer_repulsion_keeps_two_crossing_robots_apart() -> None:
    starts = [(-1.0, 2.0, 0.0), (1.0, 2.0, 0.0)]
    goals = [(1.0, -2.0, 0.0), (-1.0, -2.0, 0.0)]
    gains = Gains(kx=1.0, ky=2.0, ktheta=2.0)
    tol = Tolerance(position=0.1, heading=0.1)
    blind = simulate(BatchProblem.build(starts, goals, gains, "ccw", tol), track_separation=True)
    careful = simulate(
        BatchProblem.build(starts, goals, gains, "ccw", tol, k_avoid=1.0, peer_radius=1.0),
        max_time=120,
        track_separation=True,
    )
    assert blind.min_separation < 0.5
    assert careful.min_separation > 0.9
    assert careful.done.all()


@pytest.mark.parametrize("same", ["ccw", "cw"])
def test_swapping_robots_pass_each_other_when_both_turn_the_same_way(same: str) -> None:
    """The duality the fleet exploits: same-sense laws circle round, mixed senses collide."""
    starts = [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0)]
    goals = [(0.0, -1.0, 0.0), (0.0, 1.0, 0.0)]
    gains = Gains(kx=1.0, ky=2.0, ktheta=2.0)
    tol = Tolerance(position=0.1, heading=0.1)
    other = "cw" if same == "ccw" else "ccw"
    together = simulate(BatchProblem.build(starts, goals, gains, same, tol), track_separation=True)
    mixed = simulate(
        BatchProblem.build(starts, goals, gains, [same, other], tol), track_separation=True
    )
    assert together.done.all() and together.min_separation > 1.5
    assert mixed.min_separation < 0.1


@pytest.mark.parametrize(
    ("law", "side", "faster"),
    [("ccw", 1.0, "right"), ("cw", -1.0, "left")],
)
def test_parallel_parking_experiment_matches_section_5(law: str, side: float, faster: str) -> None:
    """ccw stays in x >= 0 with the right wheel faster; cw stays in x <= 0 with the left faster."""
    sc = SCENARIOS["parking"]
    result = run_scenario(sc, law, record=True)  # type: ignore[arg-type]
    assert result.done[0] and result.trajectory is not None
    xs = result.trajectory.poses[:, 0, 0]
    # The whole swing is on one side; the last approach may graze x = 0 by under a millimetre,
    # far inside the 5 cm position tolerance.
    assert (side * xs >= -1e-3).all()
    assert np.abs(xs).max() > 0.05  # it really swings out to that side
    right, left = wheel_speeds(
        result.trajectory.controls[:, 0, 0],
        result.trajectory.controls[:, 0, 1],
        sc.profile.wheel_radius,
        sc.profile.half_axle,
    )
    moving = (np.abs(right) + np.abs(left)) > 1e-9
    if faster == "right":
        assert (right[moving] >= left[moving]).all()
    else:
        assert (left[moving] >= right[moving]).all()


@settings(max_examples=15)
@given(st.integers(min_value=1, max_value=4), st.integers(min_value=0, max_value=10_000))
def test_groups_simulate_like_separate_batches(copies: int, seed: int) -> None:
    """``group``: copies of a scene in one batch behave like each copy on its own (peers
    and separations only within a copy), up to rounding."""
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-2, 2, size=(3, 3))
    goals = rng.uniform(-2, 2, size=(3, 3))
    gains = Gains(kx=1.0, ky=2.0, ktheta=2.0)
    tol = Tolerance(position=0.1, heading=0.1)
    laws = [["ccw", "cw"][int(b)] for b in rng.integers(0, 2, size=3 * copies)]
    alone = [
        simulate(
            BatchProblem.build(
                starts, goals, gains, laws[3 * k : 3 * k + 3], tol, k_avoid=1.0, peer_radius=1.0
            ),
            dt=0.05,
            max_time=20.0,
            track_separation=True,
        )
        for k in range(copies)
    ]
    # copies placed next to each other (overlapping!): only ``group`` keeps them apart
    together = simulate(
        BatchProblem.build(
            np.tile(starts, (copies, 1)),
            np.tile(goals, (copies, 1)),
            gains,
            laws,
            tol,
            k_avoid=1.0,
            peer_radius=1.0,
        ),
        dt=0.05,
        max_time=20.0,
        track_separation=True,
        group=3,
    )
    assert together.min_pair_distance is not None
    for k, one in enumerate(alone):
        s = slice(3 * k, 3 * k + 3)
        assert one.min_pair_distance is not None
        np.testing.assert_allclose(together.final_pose[s], one.final_pose, atol=1e-9)
        np.testing.assert_allclose(together.min_pair_distance[s, s], one.min_pair_distance)
        assert np.array_equal(together.done[s], one.done)
    off_block = np.ones((3 * copies, 3 * copies), dtype=bool)
    for k in range(copies):
        off_block[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = False
    assert np.isinf(together.min_pair_distance[off_block]).all()


def test_group_must_divide_the_batch() -> None:
    problem = BatchProblem.build(
        [(0.0, 0.0, 0.0)] * 3, [(1.0, 0.0, 0.0)] * 3, Gains(kx=1.0, ky=2.0, ktheta=2.0), "ccw"
    )
    with pytest.raises(ValueError, match="group"):
        simulate(problem, group=2)


@settings(max_examples=25)
@given(
    delay_steps=st.integers(min_value=1, max_value=150),
    x=st.floats(min_value=-4, max_value=4),
    y=st.floats(min_value=-4, max_value=4),
    theta=st.floats(min_value=-math.pi, max_value=math.pi),
)
def test_a_start_delay_shifts_the_run_by_exactly_the_delay(
    delay_steps: int, x: float, y: float, theta: float
) -> None:
    """A robot in its start delay stands still; afterwards it drives exactly as an
    undelayed robot did, so its arrival time is later by the delay and its path the same."""
    dt = 0.02
    start, goal = (x, y, theta), (0.0, 0.0, 0.0)
    gains, tol = Gains(kx=1.0, ky=2.0, ktheta=1.0), Tolerance(position=0.05, heading=0.05)
    plain = simulate(BatchProblem.build(start, goal, gains, "ccw", tol), dt=dt, max_time=120.0)
    assume(plain.done[0] and plain.time[0] > dt)  # starting inside tolerance: nothing to delay
    delayed = simulate(
        BatchProblem.build(start, goal, gains, "ccw", tol, start_delay=delay_steps * dt),
        dt=dt,
        max_time=120.0 + delay_steps * dt,
        record=True,
    )
    assert delayed.done[0]
    assert delayed.time[0] == pytest.approx(plain.time[0] + delay_steps * dt, abs=1e-9)
    assert np.array_equal(delayed.final_pose, plain.final_pose)
    assert delayed.distance[0] == plain.distance[0]
    assert delayed.trajectory is not None
    waiting = delayed.trajectory.poses[: delay_steps + 1, 0]
    assert np.all(waiting == np.asarray(start))  # stood still while waiting


def test_record_every_keeps_every_kth_step_and_the_final_pose() -> None:
    problem = BatchProblem.build(
        (2.0, 1.0, 0.5), (0.0, 0.0, 0.0), Gains(kx=1, ky=2, ktheta=1), "cw"
    )
    full = simulate(problem, dt=0.02, max_time=5.0, record=True)
    sparse = simulate(problem, dt=0.02, max_time=5.0, record=True, record_every=10)
    assert full.trajectory is not None and sparse.trajectory is not None
    steps = full.steps
    assert np.array_equal(sparse.trajectory.poses[:-1], full.trajectory.poses[:steps:10])
    assert np.array_equal(sparse.trajectory.poses[-1], full.trajectory.poses[-1])
    with pytest.raises(ValueError, match="record_every"):
        simulate(problem, record=True, record_every=0)


def test_a_large_batch_spread_over_threads_equals_its_robots_simulated_alone() -> None:
    """Above ``PARALLEL_MIN_WORK`` robots run in chunks on several threads once the parallel
    kernel is built; each robot's run is exactly the one it has in a small batch, on one
    thread or several."""
    rng = np.random.default_rng(11)
    n = step.PARALLEL_MIN_WORK + 100
    starts = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-3, 3, n)])
    goals = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-3, 3, n)])
    gains = Gains(kx=1.0, ky=2.0, ktheta=1.0)
    laws = [["ccw", "cw"][int(b)] for b in rng.integers(0, 2, n)]
    tol = Tolerance(position=0.1, heading=0.1)
    problem = BatchProblem.build(starts, goals, gains, laws, tol)
    one_thread = simulate(problem, dt=0.02, max_time=30.0, parallel=False)
    assert warm_parallel_kernel() == "ready"
    big = simulate(problem, dt=0.02, max_time=30.0)  # now spread over the threads
    assert np.array_equal(big.final_pose, one_thread.final_pose)
    picked = rng.choice(n, 40, replace=False)
    small = simulate(
        BatchProblem.build(starts[picked], goals[picked], gains, [laws[i] for i in picked], tol),
        dt=0.02,
        max_time=30.0,
    )
    assert np.array_equal(big.final_pose[picked], small.final_pose)
    assert np.array_equal(big.control_effort[picked], small.control_effort)
    assert np.array_equal(big.done[picked], small.done)
    assert big.done.any() and not big.done.all()  # some robots finish early, some do not


@pytest.mark.parametrize("law", ["cw", "ccw"])
def test_a_wall_across_the_way_is_never_touched_with_the_filter_and_crossed_without(
    law: str,
) -> None:
    """A 2 m wall (body 0.05 m) between a robot and its goal: the paper's law alone drives
    through it; with the safety filter the robot's body keeps the margin from the wall on
    every step (it may stop there: the filter guarantees clearance, not arrival)."""
    from fleet.core.simulate import obstacle_columns
    from fleet.core.wire import Obstacle

    wall = [Obstacle(x=1.5, y=-1.0, end=(1.5, 1.0), radius=0.3, body=0.05)]
    profile = RobotProfile(radius=0.2, max_wheel_speed=10.0)
    margin = 0.05
    safety = step.Safety(margin, 0.03, 5.0, 0.0)

    def run(safety: step.Safety) -> np.ndarray:
        problem = BatchProblem.build(
            (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), Gains(kx=1.0, ky=3.0, ktheta=1.0), law,
            profile=profile, safety=safety, **obstacle_columns(wall),
        )  # fmt: skip
        result = simulate(problem, dt=0.02, max_time=30.0, record=True)
        assert result.trajectory is not None
        return result.trajectory.poses[:, 0, :2]

    def clearance(xy: np.ndarray) -> np.ndarray:
        along = np.clip(xy[:, 1], -1.0, 1.0)
        return np.hypot(xy[:, 0] - 1.5, xy[:, 1] - along) - 0.2 - 0.05

    assert (run(step.SAFETY_OFF)[:, 0] > 1.5).any()  # the paper's law: straight through
    kept = run(safety)
    assert clearance(kept).min() >= margin - 1e-9
    assert (kept[:, 0] < 1.5).all() or (np.abs(kept[kept[:, 0] >= 1.5, 1]) > 1.0).all()


def test_a_process_that_defers_the_parallel_kernel_never_builds_it_in_a_batch(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The planner's process defers the parallel kernel (a minute's compile on a fresh
    install): its first large batch asks for it to be built elsewhere, and its large
    batches run on one thread until it is; any other process builds it at its first large
    batch."""
    n = step.PARALLEL_MIN_WORK + 1
    spots = np.column_stack([np.arange(n, dtype=np.float64), np.zeros(n), np.zeros(n)])
    problem = BatchProblem.build(spots, spots + 0.5, Gains(kx=1.0, ky=1.0, ktheta=1.0), "ccw")
    monkeypatch.setitem(step._parallel, "ready", False)
    asked: list[str] = []
    monkeypatch.setattr(step, "_deferral", [lambda: asked.append("build")])
    deferred = simulate(problem, dt=0.02, max_time=0.2)
    deferred_again = simulate(problem, dt=0.02, max_time=0.2)
    assert step.parallel_kernel() == "cold"
    assert asked == ["build"]  # the first large batch asked for it, once
    monkeypatch.setattr(step, "_deferral", [])
    built = simulate(problem, dt=0.02, max_time=0.2)
    assert step.parallel_kernel() == "ready"
    assert np.array_equal(built.final_pose, deferred.final_pose)
    assert np.array_equal(deferred_again.final_pose, deferred.final_pose)
