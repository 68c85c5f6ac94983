"""The switching rule between laws (17) and (20): path guarantee and what it keeps."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.params import UNLIMITED, Gains, RobotProfile, Tolerance
from fleet.core.simulate import BatchProblem, simulate
from fleet.core.step import pose_error, posture_law, saturate
from fleet.core.switching import switching_run
from fleet.core.tasks import DEFAULT_GAINS
from fleet.core.types import LAWS

FLEET_TOL = Tolerance(position=0.1, heading=0.1)
coordinate = st.floats(-5.0, 5.0, allow_nan=False)
heading = st.floats(-math.pi, math.pi, allow_nan=False)
posture = st.tuples(coordinate, coordinate, heading)
gain = st.floats(0.3, 30.0, allow_nan=False)


@settings(max_examples=15)
@given(
    starts=st.lists(posture, min_size=1, max_size=4),
    goal=posture,
    ccw=st.tuples(gain, gain, gain),
    cw=st.tuples(gain, gain, gain),
    checkpoints=st.integers(0, 12),
    limited=st.booleans(),
)
def test_never_longer_than_both_fixed_laws(
    starts: list[tuple[float, float, float]],
    goal: tuple[float, float, float],
    ccw: tuple[float, float, float],
    cw: tuple[float, float, float],
    checkpoints: int,
    limited: bool,
) -> None:
    gains = {
        "ccw": Gains(kx=ccw[0], ky=ccw[1], ktheta=ccw[2]),
        "cw": Gains(kx=cw[0], ky=cw[1], ktheta=cw[2]),
    }
    profile = RobotProfile() if limited else UNLIMITED
    run = switching_run(
        starts, goal, gains, FLEET_TOL, profile, dt=0.02, max_time=30.0, checkpoints=checkpoints
    )
    # The fixed laws, simulated on their own (not taken from the run's own bookkeeping).
    fixed = {
        law: simulate(
            BatchProblem.build(starts, goal, gains[law], law, tolerance=FLEET_TOL, profile=profile),
            dt=0.02,
            max_time=30.0,
        )
        for law in LAWS
    }
    best = np.minimum(*(np.where(fixed[law].done, fixed[law].distance, np.inf) for law in LAWS))
    arrives = best < np.inf
    assert (run.done[arrives]).all()  # arrives whenever a fixed law does
    assert (run.distance[arrives] <= best[arrives]).all()
    assert (run.switches <= checkpoints).all()
    for segments in run.segments:
        times = [seg.start_time for seg in segments]
        assert times[0] == 0.0 and times == sorted(times)
        assert all(a.law != b.law for a, b in itertools.pairwise(segments))
        # switches only at checkpoints: whole multiples of the interval
        assert all(abs(t / run.interval - round(t / run.interval)) < 1e-6 for t in times)


def test_without_checkpoints_it_is_the_better_fixed_law() -> None:
    starts = [(0.0, 2.0, 0.0), (4.0, 1.0, -0.2), (-3.0, -3.0, 2.0)]
    run = switching_run(
        starts, (0.0, 0.0, 0.5), DEFAULT_GAINS, FLEET_TOL, max_time=200.0, checkpoints=0
    )
    assert (run.switches == 0).all()
    for i, segments in enumerate(run.segments):
        law = segments[0].law
        other = "cw" if law == "ccw" else "ccw"
        assert run.distance[i] == run.fixed[law].distance[i]  # bit for bit that run
        assert run.fixed[law].done[i]
        if run.fixed[other].done[i]:
            assert run.fixed[law].distance[i] <= run.fixed[other].distance[i]


def test_switching_shortens_typical_yard_trips() -> None:
    rng = np.random.default_rng(11)
    starts = np.column_stack([rng.uniform(-5, 5, (40, 2)), rng.uniform(-math.pi, math.pi, 40)])
    goals = np.column_stack([rng.uniform(-5, 5, (40, 2)), rng.uniform(-math.pi, math.pi, 40)])
    run = switching_run(
        starts, goals, DEFAULT_GAINS, FLEET_TOL, RobotProfile(), dt=0.02, max_time=120.0
    )
    best = run.best_fixed_distance()
    assert run.done.all()
    assert (run.distance <= best).all()
    assert run.distance.mean() < best.mean()  # shorter on average: some trips did switch
    assert (run.switches > 0).any()


@settings(max_examples=200)
@given(
    pose=posture,
    goal=posture,
    gains=st.tuples(gain, gain, gain),
    cw=st.booleans(),
    limited=st.booleans(),
)
def test_position_error_never_grows_under_either_law(
    pose: tuple[float, float, float],
    goal: tuple[float, float, float],
    gains: tuple[float, float, float],
    cw: bool,
    limited: bool,
) -> None:
    # L = (x_e^2 + y_e^2)/2 is common to both laws (u = kx x_e in each, Eq. 10.d). One Euler
    # step of dt changes it by -s kx x_e^2 dt (1 - s kx dt / 2), s <= 1 the wheel-limit
    # scale: it never grows while kx dt <= 2, whichever law drives and however they switch.
    dt = 0.02
    x_e, y_e, theta_e = pose_error(*pose, *goal, cw)
    u, omega = posture_law(x_e, y_e, theta_e, *gains, cw)
    if limited:
        p = RobotProfile()
        u, omega = saturate(u, omega, p.wheel_radius, p.half_axle, p.max_wheel_speed)
    x, y, th = pose
    after = (x + math.cos(th) * float(u) * dt, y + math.sin(th) * float(u) * dt)
    before_sq = (goal[0] - x) ** 2 + (goal[1] - y) ** 2
    after_sq = (goal[0] - after[0]) ** 2 + (goal[1] - after[1]) ** 2
    assert after_sq <= before_sq + 1e-9 * max(1.0, before_sq)


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError):
        switching_run((0, 0, 0), (1, 1, 0), DEFAULT_GAINS, FLEET_TOL, checkpoints=-1)
