"""The scalar reference (plain Python) and the compiled step / batch simulator agree."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core import reference, step
from fleet.core.params import RobotProfile, Tolerance
from fleet.core.simulate import PAPER_DT, BatchProblem, SimResult, simulate
from fleet.core.types import LAWS, GainTriple, Law, Posture
from fleet.paper.reproduce import run_scenario
from fleet.paper.scenarios import CASES, SCENARIOS, CaseName

PROFILE = RobotProfile(wheel_radius=0.05, half_axle=0.135)

TWO_PI = 2.0 * math.pi
# Angles where the wraps (11.a), (11.b), (21) and their rounding guards decide.
SPECIAL_ANGLES = [
    0.0,
    -0.0,
    1e-300,
    -1e-300,
    -1e-17,
    math.pi,
    -math.pi,
    TWO_PI,
    -TWO_PI,
    math.nextafter(TWO_PI, 0.0),
    math.nextafter(-TWO_PI, 0.0),
    7.0,
    -7.0,
    -123.4,
]

heading = st.one_of(st.sampled_from(SPECIAL_ANGLES), st.floats(-20.0, 20.0))
posture = st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0), heading)
gain_triple = st.tuples(st.floats(0.3, 5.0), st.floats(0.3, 10.0), st.floats(0.3, 15.0))
law: st.SearchStrategy[Law] = st.sampled_from(LAWS)


@settings(max_examples=300)
@given(heading, heading, st.booleans())
def test_heading_error_equals_the_compiled_wrap_bit_for_bit(
    theta_goal: float, theta: float, cw: bool
) -> None:
    expected = step.heading_error(theta_goal, theta, cw)
    got = reference.heading_error(theta_goal, theta, cw)
    assert got == expected and math.copysign(1.0, got) == math.copysign(1.0, expected)
    if cw:
        assert -TWO_PI < got <= 0.0
    else:
        assert 0.0 <= got < TWO_PI


@settings(max_examples=200)
@given(posture, posture, gain_triple, law)
def test_error_and_law_equal_the_compiled_step(
    pose: Posture, goal: Posture, gains: GainTriple, law_name: str
) -> None:
    cw = law_name == "cw"
    error = reference.pose_error(pose, goal, cw)
    assert error == step.pose_error(*pose, *goal, cw)
    u, omega = reference.posture_law(error, gains, cw)
    assert (u, omega) == step.posture_law(*error, *gains, cw)
    assert (omega <= 0.0) if cw else (omega >= 0.0)


@settings(max_examples=200)
@given(
    st.floats(-20.0, 20.0),
    st.floats(-20.0, 20.0),
    st.floats(0.01, 0.2),
    st.floats(0.05, 0.5),
    st.floats(0.5, 50.0),
)
def test_saturation_equals_the_compiled_step(
    u: float, omega: float, r: float, b: float, limit: float
) -> None:
    got = reference.saturate(u, omega, reference.WheelLimit(r, b, limit))
    assert got == step.saturate(u, omega, r, b, limit)


Fleet = tuple[list[Posture], list[Posture], list[GainTriple], list[Law]]

fleets: st.SearchStrategy[Fleet] = st.integers(1, 5).flatmap(
    lambda n: st.tuples(
        st.lists(posture, min_size=n, max_size=n),
        st.lists(posture, min_size=n, max_size=n),
        st.lists(gain_triple, min_size=n, max_size=n),
        st.lists(law, min_size=n, max_size=n),
    )
)
wheel_limits = st.sampled_from([math.inf, 4.0, 15.0])


def _wheel_limit(max_wheel_speed: float) -> reference.WheelLimit:
    """The profile's wheels (an infinite limit saturates nothing; the filter's metric still
    needs the half axle)."""
    return reference.WheelLimit(PROFILE.wheel_radius, PROFILE.half_axle, max_wheel_speed)


def _simulate_batch(
    fleet: Fleet, tol: Tolerance, max_wheel_speed: float, max_time: float
) -> SimResult:
    starts, goals, gains, laws = fleet
    profile = PROFILE.model_copy(update={"max_wheel_speed": max_wheel_speed})
    problem = BatchProblem.build(starts, goals, gains, laws, tol, profile)
    return simulate(problem, dt=PAPER_DT, max_time=max_time, record=True)


@settings(max_examples=60, deadline=None)
@given(fleets, wheel_limits, st.floats(0.02, 0.3), st.floats(0.02, 0.3))
def test_batch_simulator_equals_the_scalar_loop(
    fleet: Fleet, max_wheel_speed: float, tol_position: float, tol_heading: float
) -> None:
    """Whole runs agree: stop step, effort (25), distance and final pose; both laws, with
    and without wheel-speed saturation."""
    tol = Tolerance(position=tol_position, heading=tol_heading)
    batch = _simulate_batch(fleet, tol, max_wheel_speed, max_time=3.0)
    loop = reference.simulate_loop(
        *fleet,
        tol_position=tol_position,
        tol_heading=tol_heading,
        dt=PAPER_DT,
        max_time=3.0,
        limit=_wheel_limit(max_wheel_speed),
    )
    assert batch.done.tolist() == [run.done for run in loop]
    for i, run in enumerate(loop):
        if run.done:
            assert batch.time[i] == run.time
        assert batch.control_effort[i] == pytest.approx(run.control_effort, rel=1e-9, abs=1e-9)
        assert batch.distance[i] == pytest.approx(run.distance, rel=1e-9, abs=1e-9)
        assert batch.final_pose[i].tolist() == pytest.approx(run.final_pose, rel=1e-9, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(fleets, wheel_limits)
def test_every_recorded_step_equals_one_reference_step(
    fleet: Fleet, max_wheel_speed: float
) -> None:
    """From each recorded pre-step pose, one scalar step gives the recorded error, control
    and next pose: the loops agree step by step, not only in their totals."""
    tol = Tolerance(position=0.05, heading=0.05)
    result = _simulate_batch(fleet, tol, max_wheel_speed, max_time=0.5)
    traj = result.trajectory
    assert traj is not None
    _, goals, gains, laws = fleet
    limit = _wheel_limit(max_wheel_speed)
    for i, goal in enumerate(goals):
        # A robot stands still after its last step; compare the steps it was driven.
        active_steps = round(result.time[i] / PAPER_DT) if result.done[i] else result.steps
        for k in range(active_steps):
            x, y, theta = traj.poses[k, i].tolist()
            step = reference.step((x, y, theta), goal, gains[i], laws[i] == "cw", PAPER_DT, limit)
            assert step.error == pytest.approx(traj.errors[k, i].tolist(), rel=1e-9, abs=1e-9)
            assert (step.u, step.omega) == pytest.approx(
                traj.controls[k, i].tolist(), rel=1e-9, abs=1e-9
            )
            assert step.pose == pytest.approx(traj.poses[k + 1, i].tolist(), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("law_name", LAWS)
def test_paper_scenarios_give_the_same_rows(case: CaseName, law_name: Law) -> None:
    scenario = SCENARIOS[case]
    batch = run_scenario(scenario, law_name)
    (run,) = reference.simulate_loop(
        [scenario.start],
        [scenario.goal],
        [scenario.gains[law_name].as_tuple()],
        [law_name],
        tol_position=scenario.tolerance.position,
        tol_heading=scenario.tolerance.heading,
        max_time=120.0,
    )
    assert run.done and batch.done[0]
    assert run.time == batch.time[0]
    assert run.steps == round(run.time / PAPER_DT)
    assert run.control_effort == pytest.approx(batch.control_effort[0], rel=1e-12)
    assert run.distance == pytest.approx(batch.distance[0], rel=1e-12)


def test_stop_rule_counts_the_step_that_reaches_tolerance() -> None:
    """Starting on the goal, the first step already satisfies the rule: time = (0 + 1) dt."""
    (run,) = reference.simulate_loop(
        [(1.0, 2.0, 0.5)], [(1.0, 2.0, 0.5)], [(1.0, 1.0, 1.0)], ["ccw"], max_time=1.0
    )
    assert run.done and run.steps == 1 and run.time == PAPER_DT
    assert run.control_effort == 0.0 and run.final_pose == (1.0, 2.0, 0.5)


def test_unreached_tolerance_reports_nan_time() -> None:
    (run,) = reference.simulate_loop(
        [(0.0, 0.0, 0.0)], [(5.0, 5.0, 1.0)], [(1.0, 1.0, 1.0)], ["cw"], max_time=0.2
    )
    assert not run.done and math.isnan(run.time) and run.steps == 20


def test_mismatched_lengths_are_rejected() -> None:
    with pytest.raises(ValueError, match="same length"):
        reference.simulate_loop([(0.0, 0.0, 0.0)], [], [(1.0, 1.0, 1.0)], ["ccw"])


@settings(max_examples=40, deadline=None)
@given(
    fleets,
    wheel_limits,
    st.sampled_from([0.05, 1.0, 4.0]),
    st.floats(0.5, 3.0),
    st.lists(  # posts and walls: (x, y, influence, body, end x, end y)
        st.tuples(
            st.floats(-4, 4),
            st.floats(-4, 4),
            st.floats(0.3, 2.0),
            st.floats(0.0, 0.3),
            st.floats(-4, 4),
            st.floats(-4, 4),
            st.booleans(),
        ).map(lambda o: o[:4] + (o[:2] if o[6] else o[4:6])),
        max_size=2,
    ),
    st.lists(st.sampled_from([0.0, 0.1, 0.5]), min_size=5, max_size=5),
    st.sampled_from(
        [
            None,
            reference.Safety(0.05, 0.03, 5.0, 0.0),
            reference.Safety(0.05, 0.03, 5.0, 0.04),
            reference.Safety(0.05, 0.03, 5.0, 0.04, 0.1),
        ]
    ),
    st.sampled_from([0.0, 0.25]),
)
def test_batch_with_peers_obstacles_and_delays_equals_the_reference_fleet_loop(
    fleet: Fleet,
    max_wheel_speed: float,
    k_avoid: float,
    peer_radius: float,
    obstacles: list[tuple[float, ...]],
    delays: list[float],
    safety: reference.Safety | None,
    smoothing: float,
) -> None:
    """Whole runs of robots that repel each other (Eq. 27, the paper's term or smoothed),
    keep clear through the safety filter, avoid static posts and walls and start late agree
    with the plain-Python fleet loop bit for bit."""
    starts, goals, gains, laws = fleet
    n = len(starts)
    tol = Tolerance(position=0.1, heading=0.1)
    profile = PROFILE.model_copy(update={"max_wheel_speed": max_wheel_speed, "radius": 0.2})
    problem = BatchProblem.build(
        starts, goals, gains, laws, tol, profile,
        obstacles=[o[:2] for o in obstacles], obstacle_radius=[o[2] for o in obstacles],
        obstacle_body=[min(o[3], o[2]) for o in obstacles],
        obstacle_end=[o[4:6] for o in obstacles], k_avoid=k_avoid,
        peer_radius=peer_radius, min_x_oa=0.05, start_delay=delays[:n], smoothing=smoothing,
        safety=step.SAFETY_OFF if safety is None else step.Safety(
            safety.margin, safety.projection, safety.rate, safety.spread, safety.heading
        ),
    )  # fmt: skip
    batch = simulate(problem, dt=0.02, max_time=2.0)
    avoidance = reference.Avoidance(
        k_avoid=k_avoid, peer_radius=peer_radius, min_x_oa=0.05, radius=0.2, smoothing=smoothing
    )
    runs = reference.simulate_loop(
        starts, goals, gains, laws, avoidance=avoidance,
        obstacles=[(x, y, r, min(b, r), ex, ey) for x, y, r, b, ex, ey in obstacles],
        start_delay=delays[:n],
        tol_position=0.1, tol_heading=0.1, dt=0.02, max_time=2.0,
        limit=_wheel_limit(max_wheel_speed), safety=safety,
    )  # fmt: skip
    assert batch.done.tolist() == [run.done for run in runs]
    for i, run in enumerate(runs):
        assert batch.final_pose[i].tolist() == list(run.final_pose)
        assert (batch.control_effort[i], batch.distance[i]) == (run.control_effort, run.distance)
        if run.done:
            assert batch.time[i] == run.time
