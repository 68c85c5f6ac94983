"""Rollouts of many scenes at once equal each scene simulated alone, and a rollout advanced
in segments equals one run straight through."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.params import Avoidance, RobotProfile
from fleet.core.planner.rollout import Live, Rows, World, advance, problem_of, roll_out
from fleet.core.simulate import simulate
from fleet.core.tasks import DEFAULT_GAINS
from fleet.core.wire import Obstacle

WORLD = World(RobotProfile(), Avoidance(), (Obstacle(x=0.0, y=2.5, radius=1.0),))
DT = 0.05


@st.composite
def rows(draw: st.DrawFn) -> Rows:
    """2..4 robots in a 6 m square with gains, laws, tolerances, start delays and routes."""
    n = draw(st.integers(2, 4))
    coord = st.floats(-3.0, 3.0, allow_nan=False)
    angle = st.floats(-3.0, 3.0, allow_nan=False)
    start = np.array([[draw(coord), draw(coord), draw(angle)] for _ in range(n)])
    goal = np.array([[draw(coord), draw(coord), draw(angle)] for _ in range(n)])
    cw = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    gains = np.array([DEFAULT_GAINS["cw" if c else "ccw"].as_tuple() for c in cw])
    delay = np.array(draw(st.lists(st.sampled_from([0.0, 0.5, 1.25]), min_size=n, max_size=n)))
    route = tuple(  # 0..2 via-points each: rollouts follow them across segments
        np.array([[draw(coord), draw(coord)] for _ in range(draw(st.integers(0, 2)))]).reshape(
            -1, 2
        )
        for _ in range(n)
    )
    movers = Rows(start, goal, gains, cw, np.tile([0.3, 0.5], (n, 1)), delay, route=route)
    k = draw(st.integers(0, 2))  # robots standing among them (repelling, never moving)
    still = np.array([[draw(coord), draw(coord)] for _ in range(k)]).reshape(k, 2)
    return Rows.concat([movers, Rows.standing(still)])


def alone(r: Rows, max_time: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scene simulated on its own, straight from the simulator."""
    result = simulate(problem_of(r, WORLD), dt=DT, max_time=max_time, track_separation=True)
    assert result.min_pair_distance is not None
    return result.final_pose, result.min_pair_distance, result.time


@settings(max_examples=15)
@given(st.lists(rows(), min_size=1, max_size=4))
def test_scenes_rolled_out_together_are_each_as_if_alone(scenes: list[Rows]) -> None:
    outcomes = roll_out(scenes, WORLD, dt=DT, max_time=6.0, max_rows=8)
    for r, o in zip(scenes, outcomes, strict=True):
        final, min_pair, time = alone(r, 6.0)
        np.testing.assert_allclose(o.final, final, atol=1e-9)
        np.testing.assert_allclose(o.min_pair, min_pair, atol=1e-9)
        np.testing.assert_allclose(o.time, time, atol=1e-9)
        own = roll_out([r], WORLD, dt=DT, max_time=6.0)[0]  # the same scene in a call alone
        assert own.steps == o.steps


@settings(max_examples=15)
@given(rows(), st.lists(st.sampled_from([0.5, 1.0, 2.0, 8.0]), min_size=1, max_size=6))
def test_a_rollout_advanced_in_segments_equals_one_run(r: Rows, segments: list[float]) -> None:
    """Also after robots arrived (they stand, as do the standing rows: nobody nudges them)."""
    live = Live(r)
    for duration in segments:
        advance([live], WORLD, dt=DT, duration=duration, record_every=5)
    total = live.elapsed
    final, min_pair, time = alone(r, total)
    np.testing.assert_allclose(live.pose, final, atol=1e-9)
    np.testing.assert_allclose(live.min_pair, min_pair, atol=1e-9)
    np.testing.assert_allclose(live.time, time, atol=1e-9)
    o = live.outcome()
    assert o.times is not None and o.xy is not None
    assert o.times[0] == 0.0 and np.isclose(o.times[-1], total)
    assert np.all(np.diff(o.times) > 0)
    np.testing.assert_allclose(o.xy[0], r.start[:, :2])
    np.testing.assert_allclose(o.xy[-1], final[:, :2])


def test_a_standing_row_never_moves_and_is_done_at_once() -> None:
    xy = np.array([[1.0, 2.0], [3.0, -1.0]])
    (o,) = roll_out([Rows.standing(xy)], WORLD, dt=DT, max_time=2.0)
    np.testing.assert_array_equal(o.final[:, :2], xy)
    assert o.done.all() and o.steps == 1


def test_a_standing_row_is_not_pushed_by_a_peer_beside_it() -> None:
    still = Rows.standing(np.array([[0.5, 0.0]]))
    peer = Rows(
        np.array([[0.0, 0.0, 0.0]]),
        np.array([[4.0, 0.0, 0.0]]),
        np.array([DEFAULT_GAINS["ccw"].as_tuple()]),
        np.array([False]),
        np.array([[0.1, 0.1]]),
        np.array([0.0]),
    )
    (o,) = roll_out([Rows.concat([still, peer])], WORLD, dt=DT, max_time=1.0)
    np.testing.assert_array_equal(o.final[0, :2], [0.5, 0.0])
