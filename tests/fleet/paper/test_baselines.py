"""The baselines: their equations, the shared harness, and the paper's published rows."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fleet.core import step
from fleet.core.params import UNLIMITED, Gains, RobotProfile, Tolerance
from fleet.core.simulate import BatchProblem, simulate
from fleet.core.types import FloatArray
from fleet.paper.baselines import (
    FT_GAINS,
    VFO,
    VFO_GAINS,
    EgoPolar,
    FiniteTime,
    PolarPose,
    closed_loop,
    paper_baselines,
)
from fleet.paper.baselines.harness import Policy, body_error, wrap_to_pi
from fleet.paper.reproduce import compare, run_baseline
from fleet.paper.scenarios import SCENARIOS
from fleet.paper.tables import PAPER_ROWS

TIGHT = Tolerance(position=0.05, heading=0.02)
coordinate = st.floats(-5.0, 5.0, allow_nan=False)
heading = st.floats(-math.pi, math.pi, allow_nan=False)
posture = st.tuples(coordinate, coordinate, heading)


class PaperLaw:
    """Law (17) or (20) as a harness controller, to hold the harness against the simulator."""

    def __init__(self, gains: Gains, cw: bool) -> None:
        self.gains, self.cw = np.array(gains.as_tuple()), cw
        self.name = "cw" if cw else "ccw"

    def policy(self, start: FloatArray, goal: FloatArray) -> Policy:
        kx, ky, ktheta = (float(k) for k in self.gains)

        def control(pose: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
            u, omega = np.empty(len(pose)), np.empty(len(pose))
            for i, ((x, y, th), (gx, gy, gth)) in enumerate(zip(pose, goal, strict=True)):
                error = step.pose_error(x, y, th, gx, gy, gth, self.cw)  # Eq. (5)
                u[i], omega[i] = step.posture_law(*error, kx, ky, ktheta, self.cw)
            return u, omega

        return control


@settings(max_examples=25)
@given(start=posture, goal=posture, cw=st.booleans(), limited=st.booleans())
def test_harness_runs_the_simulators_loop(
    start: tuple[float, float, float], goal: tuple[float, float, float], cw: bool, limited: bool
) -> None:
    # Same Euler step, metrics and wheel limit as fleet.core.simulate: a law run through the
    # harness passes through the simulator's poses. The harness judges the heading in
    # (-pi, pi], the simulator in the law's wrap (Eqs. 11, 21), which is stricter: a small
    # negative theta_e is near 2 pi there and law (17) turns once more (Hypothesis found
    # 0.24 s against 23.29 s). So the harness stops first, where the simulator also is.
    gains = Gains(kx=1.0, ky=2.0, ktheta=1.5)
    profile = RobotProfile() if limited else UNLIMITED
    tol = Tolerance(position=0.1, heading=0.1)
    law = "cw" if cw else "ccw"
    problem = BatchProblem.build(start, goal, gains, law, tolerance=tol, profile=profile)
    ours = closed_loop(PaperLaw(gains, cw), start, goal, tol, max_time=30.0, profile=profile)
    full = simulate(problem, dt=0.01, max_time=30.0)
    assert ours.done[0] or not full.done[0]
    if not ours.done[0]:
        return
    assert not full.done[0] or ours.time[0] <= full.time[0] + 1e-9
    theirs = simulate(problem, dt=0.01, max_time=ours.time[0])  # the same number of steps
    np.testing.assert_allclose(ours.final_pose, theirs.final_pose, atol=1e-9)
    assert ours.distance[0] == pytest.approx(theirs.distance[0], rel=1e-9)
    assert ours.control_effort[0] == pytest.approx(theirs.control_effort[0], rel=1e-9)
    if theirs.done[0]:  # both stop rules held at this step
        assert ours.time[0] == pytest.approx(theirs.time[0])


def test_body_error_is_eq_5_with_the_heading_in_minus_pi_pi() -> None:
    x_e, y_e, theta_e = body_error(
        np.array([[1.0, 1.0, math.pi / 2]]), np.array([[1.0, 3.0, -3.0]])
    )
    assert (x_e[0], y_e[0]) == pytest.approx((2.0, 0.0), abs=1e-12)
    assert theta_e[0] == pytest.approx(-3.0 - math.pi / 2 + 2 * math.pi)
    assert wrap_to_pi(math.pi) == pytest.approx(math.pi)
    assert wrap_to_pi(-math.pi) == pytest.approx(math.pi)


def test_vfo_first_control_is_the_convergence_field_by_hand() -> None:
    # Case I, k1 = 10, kp = 5, eta = 3 (Table 2), sigma = +1, robot at (0, 2, 0):
    # e* = (2, -3), g_t = (cos pi/4, sin pi/4), h* = kp e* - eta ||e*|| g_t,
    # u = h*.g(0) = h_x, theta_a = atan2(h_y, h_x), omega = k1 theta_a + d(theta_a)/dt.
    start, goal = np.array([[0.0, 2.0, 0.0]]), np.array([[2.0, -1.0, math.pi / 4]])
    norm = math.sqrt(13.0)
    hx = 10.0 - 3.0 * norm * math.sqrt(0.5)
    hy = -15.0 - 3.0 * norm * math.sqrt(0.5)
    u = hx
    de = (-u, 0.0)  # e* changes by -g(theta) u
    dnorm = (2.0 * de[0] - 3.0 * de[1]) / norm
    dhx = 5.0 * de[0] - 3.0 * dnorm * math.sqrt(0.5)
    dhy = 5.0 * de[1] - 3.0 * dnorm * math.sqrt(0.5)
    dtheta_a = (dhy * hx - hy * dhx) / (hx * hx + hy * hy)
    omega = 10.0 * math.atan2(hy, hx) + dtheta_a
    got_u, got_omega = VFO(k1=10.0, kp=5.0, eta=3.0, sigma=1.0).policy(start, goal)(start, 0.0)
    assert got_u[0] == pytest.approx(u)
    assert got_omega[0] == pytest.approx(omega)


def test_vfo_decision_factor_follows_the_initial_error() -> None:
    # sigma = sgn(e*(0).g_t): goal ahead along its heading -> forward; behind -> backward.
    goal = np.array([[0.0, 0.0, 0.0]])
    vfo = VFO(k1=2.0, kp=2.0, eta=1.0)
    behind = np.array([[-3.0, 0.5, 0.0]])  # e*.g_t = 3 > 0: drives forward
    ahead = np.array([[3.0, 0.5, 0.0]])  # e*.g_t = -3 < 0: backs in
    assert vfo.policy(behind, goal)(behind, 0.0)[0][0] > 0
    assert vfo.policy(ahead, goal)(ahead, 0.0)[0][0] < 0
    for start in (behind, ahead):
        run = closed_loop(vfo, start, goal, TIGHT)
        assert run.done[0]
        assert run.distance[0] < 3.6  # a near-straight approach, no detour


@settings(max_examples=20)
@given(start=posture, goal=posture)
@example(start=(0.0, 0.0, 0.0), goal=(0.0, 0.03125, 0.0))  # done at step 0 (Hypothesis)
def test_vfo_reaches_any_posture(
    start: tuple[float, float, float], goal: tuple[float, float, float]
) -> None:
    vfo = VFO(k1=10.0, kp=5.0, eta=3.0)
    run = closed_loop(vfo, start, goal, TIGHT, max_time=30.0, record=True)
    assert run.done[0] and run.trajectory is not None
    # The stop rule judges the pre-step error of the last step (which is still applied).
    last = round(run.time[0] / 0.01) - 1
    x_e, y_e, theta_e = run.trajectory.errors[last, 0]
    assert math.hypot(x_e, y_e) < TIGHT.position and abs(theta_e) < TIGHT.heading
    assert run.trajectory.controls.shape[0] == last + 1  # nothing applied after it


def test_ft_switches_phase_at_t_with_a_jump_of_the_linear_velocity() -> None:
    ft = FT_GAINS["III"]
    scenario = SCENARIOS["III"]
    run = run_baseline(scenario, ft, record=True)
    assert run.done[0]
    assert run.trajectory is not None
    u = run.trajectory.controls[:, 0, 0]
    theta_bar = run.trajectory.poses[:-1, 0, 2] - scenario.goal[2]
    u1 = u * np.cos(theta_bar)  # dx1/dt of the chained form
    k = round(ft.T / 0.01)
    np.testing.assert_allclose(u1[:k], ft.K1)  # phase 1: along the goal axis at K1
    assert u1[k - 1] > 0 > u1[k]  # phase 2 turns back: the discontinuity the paper names
    assert abs(u1[k] - u1[k - 1]) > ft.K1


@settings(max_examples=20)
@given(
    start=st.tuples(coordinate, coordinate, st.floats(-1.2, 1.2)),
    goal=st.tuples(coordinate, coordinate, st.just(0.0)),
)
def test_ft_reaches_goals_within_its_chained_form_domain(
    start: tuple[float, float, float], goal: tuple[float, float, float]
) -> None:
    # tan(theta_bar) is the chained form's state: |theta_bar| < pi/2 is its domain.
    run = closed_loop(FT_GAINS["III"], start, goal, Tolerance(position=0.1, heading=0.1))
    assert run.done[0]


def test_ft_rejects_non_positive_gains() -> None:
    with pytest.raises(ValueError, match="positive"):
        FiniteTime(K1=1, K2=1, k1=1, k2=1, alpha1=0.5, alpha2=0.0, T=1)


def test_astolfi_is_move_to_pose_and_backs_up_to_a_goal_behind() -> None:
    law = PolarPose()
    goal = np.array([[0.0, 0.0, 0.0]])
    pose = np.array([[1.0, 0.2, 0.3]])  # goal behind: alpha beyond pi/2
    u, omega = law.policy(pose, goal)(pose, 0.0)
    rho = math.hypot(1.0, 0.2)
    alpha = math.atan2(-0.2, -1.0) - 0.3
    alpha = (alpha + math.pi) % (2 * math.pi) - math.pi
    beta = (0.0 - 0.3 - alpha + math.pi) % (2 * math.pi) - math.pi
    assert u[0] == pytest.approx(-min(9.0 * rho, 15.0))
    assert omega[0] == pytest.approx(float(np.clip(15.0 * alpha - 3.0 * beta, -7.0, 7.0)))


def test_park_kuipers_curvature_is_nav2s_smooth_control_law() -> None:
    law = EgoPolar(initial_rotation=math.inf)
    goal = np.array([[2.0, 1.0, 0.5]])
    pose = np.array([[0.0, 0.0, 0.2]])
    u, omega = law.policy(pose, goal)(pose, 0.0)
    r = math.hypot(2.0, 1.0)
    sight = math.atan2(1.0, 2.0)
    phi, delta = 0.5 - sight, 0.2 - sight
    kappa = (
        -(
            1.0 * (delta - math.atan(-2.0 * phi))
            + (1 + 2.0 / (1 + (2.0 * phi) ** 2)) * math.sin(delta)
        )
        / r
    )
    v = min(1.0 / (1 + 0.4 * kappa**2), 1.0 * r / 1.5)
    v = min(max(v, 0.1), 1.0)
    w = max(min(kappa * v, 1.0), -1.0)
    assert omega[0] == pytest.approx(w)
    assert u[0] == pytest.approx(w / kappa)


def test_park_kuipers_turns_in_place_to_face_the_target_and_at_the_goal() -> None:
    law = EgoPolar()
    goal = np.array([[0.0, 0.0, 1.0]])
    behind = np.array([[2.0, 0.0, 0.0]])  # target straight behind: turn on the spot
    u, omega = law.policy(behind, goal)(behind, 0.0)
    assert u[0] == 0.0 and abs(omega[0]) >= 0.25
    there = np.array([[0.01, 0.0, 0.0]])  # inside the final radius: turn to the goal heading
    u, omega = law.policy(there, goal)(there, 0.0)
    assert u[0] == 0.0 and omega[0] == pytest.approx(0.5 * 1.0 * 1.0)


@pytest.mark.parametrize("case", ["I", "II", "III"])
def test_every_baseline_parks_in_the_comparative_cases(case: str) -> None:
    scenario = SCENARIOS[case]  # type: ignore[index]
    for controller in paper_baselines(scenario.name):
        run = run_baseline(scenario, controller)
        assert run.done[0], controller.name
        assert run.distance[0] >= math.dist(scenario.start[:2], scenario.goal[:2])


def test_vfo_matches_table_9_on_effort_and_distance() -> None:
    # Case III is the one VFO row that the original equations reproduce (docs/paper.md): effort
    # and distance within 2 % of Table 9.
    row = PAPER_ROWS[("III", "VFO")]
    run = run_baseline(SCENARIOS["III"], VFO_GAINS["III"])
    assert run.control_effort[0] == pytest.approx(row.control_effort, rel=0.02)
    assert run.distance[0] == pytest.approx(row.distance, rel=0.02)


def test_comparison_rows_carry_the_papers_rows_and_deviations() -> None:
    rows = compare(("III",))
    names = [r.controller for r in rows]
    assert names == ["(17) ccw", "(20) cw", "VFO", "FT", "Astolfi", "Park-Kuipers"]
    vfo = rows[2]
    assert vfo.paper == PAPER_ROWS[("III", "VFO")]
    dev = vfo.deviation()
    assert dev is not None
    assert dev["distance"] == pytest.approx(vfo.distance / 7.6685 - 1.0)
    assert dev["time"] == pytest.approx(vfo.time - 1.68)
    assert rows[0].paper is None and rows[0].deviation() is None and not rows[0].matches_paper()
