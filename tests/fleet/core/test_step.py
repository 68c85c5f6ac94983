"""The one compiled control step: properties, the plain-Python oracle, one robot == N robots."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core import reference, step
from fleet.core.types import LAWS, FloatArray, GainTriple, Law, Posture

TWO_PI = 2.0 * math.pi
R, B = 0.05, 0.135  # wheel radius and half axle [m] (Table 10)

coord = st.floats(-6.0, 6.0)
angle = st.floats(-20.0, 20.0)
posture = st.tuples(coord, coord, angle)
gain_triple = st.tuples(st.floats(0.3, 5.0), st.floats(0.3, 10.0), st.floats(0.3, 15.0))
law: st.SearchStrategy[Law] = st.sampled_from(LAWS)
point = st.tuples(coord, coord)
body_st = st.builds(
    reference.Body, coord, coord, angle, st.floats(0.05, 0.4), st.sampled_from([0.0, 0.05, 0.5])
)
peers_st = st.lists(body_st, max_size=6)
#: Posts (both ends the same) and wall segments: (x, y, influence, body, end x, end y).
obstacles_st = st.lists(
    st.floats(0.2, 3.0).flatmap(
        lambda r: st.tuples(coord, coord, st.just(r), st.floats(0.0, r)).flatmap(
            lambda o: st.one_of(st.just(o + o[:2]), st.tuples(coord, coord).map(lambda e: o + e))
        )
    ),
    max_size=3,
)
safety_st = st.sampled_from(
    [
        None,
        reference.Safety(0.05, 0.03, 5.0, 0.0),
        reference.Safety(0.1, 0.05, 2.0, 0.02),
        reference.Safety(0.05, 0.03, 5.0, 0.03, 0.05),  # a predicted heading's uncertainty
        reference.Safety(0.05, 0.03, 20.0, 0.0, 0.9),  # a cone wider than 45 degrees
        reference.Safety(0.05, 0.03, 5.0, 0.02, 1.6),  # beyond 90 degrees: any direction
    ]
)
limits = st.sampled_from([math.inf, 4.0, 20.0])
avoidance_st = st.builds(
    reference.Avoidance,
    k_avoid=st.sampled_from([0.0, 0.05, 1.0, 4.0]),
    peer_radius=st.floats(0.3, 3.0),
    min_x_oa=st.floats(0.01, 0.2),
    radius=st.floats(0.05, 0.4),
    smoothing=st.sampled_from([0.0, 0.25]) | st.floats(0.01, 1.0),
)


def _params(
    goal: Posture,
    gains: GainTriple,
    law_name: Law,
    limit: float,
    radius: float,
    smoothing: float = 0.0,
) -> FloatArray:
    one = np.array
    return step.robot_params(
        one([goal]), one([gains]), one([1.0 if law_name == "cw" else 0.0]), one([0.1]),
        one([0.1]), one([R]), one([B]), one([limit]), one([radius]), smoothing=smoothing,
    )  # fmt: skip


@dataclass(frozen=True)
class Situation:
    """One robot's step to take: its posture, task, wheel limit, avoidance and surroundings."""

    pose: Posture
    goal: Posture
    gains: GainTriple
    law: Law
    limit: float  # [rad/s]
    avoidance: reference.Avoidance
    peers: list[reference.Body]
    obstacles: list[reference.ObstacleRow]
    safety: reference.Safety | None = None
    on_via: bool = False  # the goal is a via-point the robot faces (the filter's side)

    def compiled(self, limit: float | None = None) -> step.StepResult:
        """The compiled step (``limit`` overrides the wheel limit)."""
        wheel_limit = self.limit if limit is None else limit
        params = _params(
            self.goal,
            self.gains,
            self.law,
            wheel_limit,
            self.avoidance.radius,
            self.avoidance.smoothing,
        )
        params[0, step.ON_VIA] = 1.0 if self.on_via else 0.0
        bodies = np.array(
            [(b.x, b.y, b.theta, b.radius, b.spread) for b in self.peers], dtype=np.float64
        ).reshape(-1, 5)
        safety = self.safety
        return step.step_robot(
            self.pose,
            params,
            peers=bodies[:, :3].T.copy(),
            shapes=bodies[:, 3:].T.copy(),
            obstacles=np.array(self.obstacles, dtype=np.float64).reshape(-1, 6).T.copy(),
            k_avoid=self.avoidance.k_avoid,
            peer_radius=self.avoidance.peer_radius,
            min_x_oa=self.avoidance.min_x_oa,
            safety=step.SAFETY_OFF
            if safety is None
            else step.Safety(
                safety.margin, safety.projection, safety.rate, safety.spread, safety.heading
            ),
            dt=0.02,
        )


situations = st.builds(
    Situation,
    posture,
    posture,
    gain_triple,
    law,
    limits,
    avoidance_st,
    peers_st,
    obstacles_st,
    safety_st,
    st.booleans(),
)


# -- the pieces --------------------------------------------------------------------------------
SPECIAL_ANGLES = [0.0, -0.0, 1e-300, -1e-300, -1e-17, math.pi, -math.pi, TWO_PI, -TWO_PI,
                  math.nextafter(TWO_PI, 0.0), math.nextafter(-TWO_PI, 0.0), 7.0, -7.0,
                  -123.4, 4 * math.pi, 6 * math.pi, -4 * math.pi, 1e6, -1e6]  # fmt: skip
heading = st.one_of(st.sampled_from(SPECIAL_ANGLES), st.floats(-50.0, 50.0))


@settings(max_examples=500)
@given(heading)
def test_the_exact_remainder_wrap_is_python_modulo_bit_for_bit(theta: float) -> None:
    """(11.a) without ``fmod`` on the common range equals ``theta % 2pi`` exactly."""
    got = step.wrap_to_2pi(theta)
    expected = reference.wrap_to_2pi(theta)
    assert got == expected and math.copysign(1.0, got) == math.copysign(1.0, expected)
    assert 0.0 <= got < TWO_PI


@settings(max_examples=300)
@given(heading, heading, st.booleans())
def test_heading_error_wraps_per_law_and_equals_the_reference(
    theta_goal: float, theta: float, cw: bool
) -> None:
    got = step.heading_error(theta_goal, theta, cw)
    assert got == reference.heading_error(theta_goal, theta, cw)
    if cw:
        assert -TWO_PI < got <= 0.0  # (21)
    else:
        assert 0.0 <= got < TWO_PI  # (11.b)
    assert math.isclose(math.cos(got), math.cos(theta_goal - theta), abs_tol=1e-9)


@given(posture, posture, st.booleans())
def test_pose_error_is_the_goal_in_the_robot_frame(pose: Posture, goal: Posture, cw: bool) -> None:
    x_e, y_e, _ = step.pose_error(*pose, *goal, cw)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    assert math.isclose(pose[0] + c * x_e - s * y_e, goal[0], abs_tol=1e-9)
    assert math.isclose(pose[1] + s * x_e + c * y_e, goal[1], abs_tol=1e-9)


@given(
    st.floats(-5, 5), st.floats(-10, 10), st.floats(0.01, 0.5), st.floats(0.05, 1.0),
    st.floats(0.1, 50),
)  # fmt: skip
def test_saturation_respects_the_wheel_limit_and_keeps_the_curvature(
    u: float, omega: float, r: float, b: float, limit: float
) -> None:
    us, ws = step.saturate(u, omega, r, b, limit)
    right, left = step.wheel_speeds(us, ws, r, b)
    assert max(abs(right), abs(left)) <= limit * (1 + 1e-12)
    # Same direction, scaled by one factor in (0, 1]: the path curvature omega/u is kept.
    assert us * u >= 0 and ws * omega >= 0
    assert abs(us) <= abs(u) and abs(ws) <= abs(omega)
    assert math.isclose(us * omega, ws * u, rel_tol=1e-9, abs_tol=1e-12)
    r0, l0 = step.wheel_speeds(u, omega, r, b)
    if max(abs(r0), abs(l0)) <= limit:  # below the limit nothing changes
        assert (us, ws) == (u, omega)


@given(st.floats(-3, 3), st.floats(-3, 3), st.floats(0.01, 0.5), st.floats(0.05, 1.0))
def test_wheel_speeds_invert_equation_2(u: float, omega: float, r: float, b: float) -> None:
    u2, w2 = step.body_velocities(*step.wheel_speeds(u, omega, r, b), r, b)
    assert math.isclose(u2, u, abs_tol=1e-9) and math.isclose(w2, omega, abs_tol=1e-9)


@given(st.floats(-3, 3), st.floats(0.0, 3.0), st.floats(0.1, 10), st.floats(0.01, 0.2))
def test_repulsion_term_is_bounded_and_pushes_away(
    x_oa: float, distance: float, k_avoid: float, min_x_oa: float
) -> None:
    du = step.repulsion_term(x_oa, distance * distance, 3.0, k_avoid, min_x_oa, 0.0)
    assert abs(du) <= k_avoid / min_x_oa  # the guard bounds the singular term
    assert du < 0 if x_oa >= 0 else du > 0  # ahead (or abeam): back off; behind: go on
    if abs(x_oa) >= min_x_oa:
        assert du == -k_avoid / x_oa  # Eq. (27) exactly, however deep in the radius


@given(
    st.floats(-3, 3),
    st.floats(0.0, 1.0),
    st.floats(0.1, 10),
    st.floats(0.01, 0.2),
    st.floats(0.05, 0.5),
    st.floats(1e-6, 1e-3),
)
def test_the_smoothed_term_is_continuous_bounded_and_the_papers_inside_its_bands(
    x_oa: float, depth: float, k_avoid: float, min_x_oa: float, w: float, h: float
) -> None:
    """With smoothing w: no jump at the influence radius nor abeam (a small move of the core
    changes the term by a bounded slope times the move), never stronger than the paper's
    term, pushing the same way, and the paper's term exactly away from both bands."""
    influence = 1.0 + w

    def term(x: float, d: float) -> float:
        return step.repulsion_term(x, d * d, influence, k_avoid, min_x_oa, w)

    distance = influence - depth * (influence - 0.01)  # from the edge (depth 0) inwards
    du = term(x_oa, distance)
    band = max(w, min_x_oa)
    paper = step.repulsion_term(x_oa, distance * distance, influence, k_avoid, min_x_oa, 0.0)
    assert abs(du) <= abs(paper) + 1e-12 and abs(du) <= k_avoid / band + 1e-12
    assert du <= 0 if x_oa >= 0 else du >= 0
    assert term(x_oa, influence) == 0.0 and term(0.0, distance) == 0.0
    slope = k_avoid / band**2 + k_avoid / (band * w)  # Lipschitz in x_OA and in distance
    assert abs(term(x_oa + h, distance) - du) <= slope * h * (1 + 1e-9)
    if distance - h > 0:
        assert abs(term(x_oa, distance - h) - du) <= slope * h * (1 + 1e-9)
    if abs(x_oa) >= band and distance <= influence - w:
        assert du == -k_avoid / x_oa


# -- the whole step ----------------------------------------------------------------------------
@settings(max_examples=400, deadline=None)
@given(situations)
def test_compiled_step_equals_the_plain_python_reference(sit: Situation) -> None:
    """Same order of operations and libm: error, control, repulsion, the safety filter and
    next pose agree bit for bit, with and without peers, obstacles, filter and wheel limit,
    for both laws."""
    got = sit.compiled()
    wheel = reference.WheelLimit(R, B, sit.limit)
    ref = reference.step(
        sit.pose, sit.goal, sit.gains, sit.law == "cw", 0.02,
        wheel, avoidance=sit.avoidance, peers=sit.peers,
        obstacles=sit.obstacles, safety=sit.safety, on_via=sit.on_via,
    )  # fmt: skip
    assert (got.x_e, got.y_e, got.theta_e) == ref.error
    assert (got.u, got.omega, got.repulsion, got.avoiding) == (
        ref.u, ref.omega, ref.repulsion, ref.avoiding,
    )  # fmt: skip
    assert (got.x, got.y, got.theta) == ref.pose
    assert got.done == reference.within_tolerance(ref.error, 0.1, 0.1)


#: Peers 0.3-3 m from the robot in any direction: the filter's cull (a peer too far to
#: bind is skipped before its projected point is computed) lies in this range.
nearby_peers_st = st.lists(
    st.tuples(st.floats(0.3, 3.0), st.floats(-math.pi, math.pi), angle, body_st), max_size=4
)


@settings(max_examples=300, deadline=None)
@given(situations, nearby_peers_st, safety_st.filter(lambda s: s is not None))
def test_the_filter_s_cull_skips_only_peers_the_reference_skips(
    sit: Situation,
    nearby: list[tuple[float, float, float, reference.Body]],
    safety: reference.Safety,
) -> None:
    """Peers around the cull's distance: the compiled step still equals the reference,
    which computes every peer's constraint and drops those that cannot bind."""
    x, y, _ = sit.pose
    peers = [
        reference.Body(
            x + d * math.cos(bearing), y + d * math.sin(bearing), theta, body.radius, body.spread
        )
        for d, bearing, theta, body in nearby
    ]
    near = Situation(
        sit.pose, sit.goal, sit.gains, sit.law, sit.limit, sit.avoidance, peers, [], safety,
        sit.on_via,
    )  # fmt: skip
    got = near.compiled()
    ref = reference.step(
        near.pose, near.goal, near.gains, near.law == "cw", 0.02,
        reference.WheelLimit(R, B, near.limit), avoidance=near.avoidance, peers=peers,
        obstacles=[], safety=safety, on_via=near.on_via,
    )  # fmt: skip
    assert (got.u, got.omega, got.avoiding) == (ref.u, ref.omega, ref.avoiding)
    assert (got.x, got.y, got.theta) == ref.pose


@settings(max_examples=300, deadline=None)
@given(situations)
def test_omega_sign_wheel_limit_and_curvature_hold_for_every_step(sit: Situation) -> None:
    got = sit.compiled()
    if sit.safety is None:  # the filter may turn either way to keep a body clear
        assert got.omega >= 0.0 if sit.law == "ccw" else got.omega <= 0.0  # (17) / (20)
    assert max(abs(got.right), abs(got.left)) <= sit.limit * (1 + 1e-12)
    assert math.isclose(R / 2 * (got.right + got.left), got.u, abs_tol=1e-12)
    assert math.isclose(R / (2 * B) * (got.right - got.left), got.omega, abs_tol=1e-12)
    # saturation divides u + repulsion and omega by one factor: the curvature is kept
    # (the filter, when on, may change it)
    free = sit.compiled(limit=math.inf)
    if sit.safety is None and got.u != 0.0 and free.u != 0.0:
        assert math.isclose(got.omega * free.u, free.omega * got.u, rel_tol=1e-9, abs_tol=1e-12)


@settings(max_examples=400, deadline=None)
@given(
    st.floats(-math.pi, math.pi),
    st.floats(0.0, 2 * math.pi),
    st.floats(0.0, 0.53),
    posture,
    gain_triple,
    law,
    st.sampled_from([0.0, 0.05, 1.0, 4.0]),
    peers_st,
    st.booleans(),
)
def test_the_filter_never_closes_on_a_peer_at_the_margin(
    heading_: float,
    bearing: float,
    distance: float,
    goal: Posture,
    gains: GainTriple,
    law_name: Law,
    k_avoid: float,
    others: list[reference.Body],
    on_via: bool,
) -> None:
    """With the projected discs at or within the margin of a peer's, whatever the law, the
    gains, the other peers and the side the filter aims at (a via leg's or the law's): the
    step never brings the discs closer (the barrier's bound is <= 0 there; the
    second-order allowance is part of it)."""
    avoidance = reference.Avoidance(k_avoid=k_avoid, peer_radius=1.0, min_x_oa=0.05, radius=0.2)
    safety = reference.Safety(0.05, 0.03, 5.0, 0.0)
    peer = reference.Body(distance * math.cos(bearing), distance * math.sin(bearing), 0.0, 0.2)
    pose = (0.0, 0.0, heading_)
    got = Situation(
        pose, goal, gains, law_name, 20.0, avoidance, [*others, peer], [], safety, on_via
    ).compiled()

    def disc_gap(x: float, y: float, theta: float) -> float:
        return math.dist(
            (x + 0.03 * math.cos(theta), y + 0.03 * math.sin(theta)), (peer.x + 0.03, peer.y)
        )

    assert (
        disc_gap(got.x, got.y, got.theta) >= disc_gap(*pose) - 1e-12
        or disc_gap(got.x, got.y, got.theta) >= 2 * 0.23 + 0.05
    )


def test_the_filter_is_off_in_the_papers_model() -> None:
    off = reference.Avoidance(k_avoid=0.0, peer_radius=1.0, min_x_oa=0.05, radius=0.2)
    peer = reference.Body(0.3, 0.0, 0.0, 0.2)
    got = Situation(
        (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (1.0, 1.0, 1.0), "ccw", 20.0, off, [peer], []
    ).compiled()
    assert got.u > 0.0 and not got.avoiding


def test_a_held_robot_stands_still_but_the_stop_rule_is_checked() -> None:
    params = _params((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), "ccw", 20.0, 0.2)
    for pose, done in (((0.0, 0.0, 0.0), True), ((1.0, 1.0, 0.0), False)):
        got = step.step_robot(
            pose, params, hold=True, peers=np.zeros((3, 0)), shapes=np.zeros((2, 0)),
            obstacles=np.zeros((4, 0)),
            k_avoid=4.0, peer_radius=1.0, min_x_oa=0.05, dt=0.02,
        )  # fmt: skip
        assert (got.u, got.omega, got.right, got.left) == (0.0, 0.0, 0.0, 0.0)
        assert (got.x, got.y, got.theta) == pose and got.done is done


def test_compiled_entry_points_refuse_other_types_instead_of_compiling() -> None:
    with pytest.raises(TypeError):
        step.wrap_to_2pi("1.0")  # type: ignore[arg-type]
    assert len(step.wrap_to_2pi.signatures) == 1


# -- one robot == N robots -----------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(
    st.integers(2, 7).flatmap(
        lambda n: st.tuples(
            st.lists(posture, min_size=n, max_size=n),
            st.lists(posture, min_size=n, max_size=n),
            st.lists(law, min_size=n, max_size=n),
        )
    ),
    st.sampled_from([0.05, 4.0]),
    st.sampled_from(
        [
            step.SAFETY_OFF,
            step.Safety(0.05, 0.03, 5.0, 0.02),
            step.Safety(0.05, 0.03, 5.0, 0.0, 0.1),
        ]
    ),
)
def test_one_robot_step_equals_its_row_of_the_batch_step(
    fleet: tuple[list[Posture], list[Posture], list[Law]], k_avoid: float, safety: step.Safety
) -> None:
    """The agent's one-robot call, given the others as peers, is the batch kernel's row."""
    starts, goals, laws = fleet
    n = len(starts)
    gains = (1.0, 2.0, 1.0)
    params = np.vstack(
        [_params(g, gains, lw, 20.0, 0.2) for g, lw in zip(goals, laws, strict=True)]
    )
    pose = np.array(starts, dtype=np.float64).T.copy()
    done, metrics = np.full(n, -1, dtype=np.int64), np.zeros((2, n))
    interaction = step.Interaction(
        group=n, k_avoid=k_avoid, peer_radius=2.0, min_x_oa=0.05, safety=safety
    )
    schedule = step.Schedule(dt=0.02, first_step=0, max_steps=1)
    step.advance_batch(pose, params, done, metrics, np.zeros((4, 0)), interaction, schedule)
    for i in range(n):
        others = np.array([p for j, p in enumerate(starts) if j != i]).T.copy()
        shapes = np.vstack([np.full(n - 1, 0.2), np.full(n - 1, safety.spread)])
        one = step.step_robot(
            starts[i], params[i : i + 1].copy(), peers=others, shapes=shapes,
            obstacles=np.zeros((4, 0)), k_avoid=k_avoid, peer_radius=2.0, min_x_oa=0.05,
            safety=safety, dt=0.02,
        )  # fmt: skip
        assert (one.x, one.y, one.theta) == tuple(pose[:, i])
        assert (done[i] == 0) == one.done
        assert metrics[step.EFFORT, i] == (abs(one.omega) + abs(one.u)) * 0.02


def test_integrate_wheels_is_the_step_euler_update() -> None:
    params = _params((3.0, 1.0, 0.5), (1.0, 2.0, 1.0), "cw", 20.0, 0.2)
    got = step.step_robot(
        (0.2, -0.1, 0.3), params, peers=np.zeros((3, 0)), shapes=np.zeros((2, 0)),
        obstacles=np.zeros((4, 0)),
        k_avoid=0.0, peer_radius=1.0, min_x_oa=0.05, dt=0.02,
    )  # fmt: skip
    x, y, theta = step.integrate_wheels(0.2, -0.1, 0.3, got.right, got.left, R, B, 0.02, 1)
    assert (x, y, theta) == pytest.approx((got.x, got.y, got.theta), abs=1e-15)


@settings(max_examples=60, deadline=None)
@given(posture, posture, posture, law, st.sampled_from([0.0, 4.0]))
def test_the_law_and_eq_27_act_on_the_nominal_pose_the_rest_on_the_measured_one(
    pose: Posture, nominal: Posture, goal: Posture, which: Law, k_avoid: float
) -> None:
    """The agent's latency compensation: with a ``nominal`` pose the law and Eq. (27) give
    the command they give at that pose; the error, the stop rule and the Euler step are the
    measured pose's; the nominal pose equal to the measured one is no nominal at all."""
    params = _params(goal, (1.0, 2.0, 1.0), which, 20.0, 0.2)
    post = np.array([[0.5], [0.5], [1.5], [0.1], [0.5], [0.5]])  # start, radii, end

    def at(where: Posture, nominal: Posture | None = None) -> step.StepResult:
        return step.step_robot(
            where, params, peers=np.zeros((3, 0)), shapes=np.zeros((2, 0)), obstacles=post,
            k_avoid=k_avoid, peer_radius=1.0, min_x_oa=0.05, dt=0.02, nominal=nominal,
        )  # fmt: skip

    mixed, there, here = at(pose, nominal), at(nominal), at(pose)
    assert (mixed.u, mixed.omega, mixed.repulsion) == (there.u, there.omega, there.repulsion)
    assert (mixed.x_e, mixed.y_e, mixed.theta_e, mixed.done) == (
        here.x_e, here.y_e, here.theta_e, here.done,
    )  # fmt: skip
    x, y, theta = step.integrate_wheels(*pose, mixed.right, mixed.left, R, B, 0.02, 1)
    assert (x, y, theta) == pytest.approx((mixed.x, mixed.y, mixed.theta), abs=1e-12)
    assert at(pose, pose) == here
