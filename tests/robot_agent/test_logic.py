"""Pure per-tick logic of the robot agent: task protocol, modes, avoidance, wheel limit."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
import support
from hypothesis import given, settings
from hypothesis import strategies as st
from support import TEST_GAINS

from fleet.core import reference
from fleet.core.params import Avoidance, RobotProfile, SafetyConfig
from fleet.core.types import FloatArray, Posture
from fleet.core.wire import CancelAssignment, Obstacle, ParkAssignment, RobotMode
from robot_agent.link import link_is_up
from robot_agent.logic import (
    AgentTask,
    AgentTaskStatus,
    TickResult,
    apply_assignment,
    decide,
    obstacle_arrays,
    within_tolerance,
)

PROFILE = RobotProfile()  # r = 0.05 m, b = 0.135 m, 20 rad/s
NO_PEERS = np.zeros((0, 2))
NO_OBSTACLES = obstacle_arrays([])
SAFETY = SafetyConfig()


def bodies(centres: FloatArray, spread: float = 0.0) -> tuple[FloatArray, FloatArray]:
    """Peers at ``centres`` (M, 2) [m], heading 0, radius 0.2 m, with ``spread`` [m]."""
    m = centres.shape[0]
    postures = np.vstack([centres.T, np.zeros((1, m))]) if m else np.zeros((3, 0))
    return postures, np.vstack([np.full(m, 0.2), np.full(m, spread)])


def park(task_id: str = "t1", goal: Posture = (3.0, 0.0, 0.0), **fields: Any) -> ParkAssignment:
    return support.park("r1", task_id, goal, **fields)


DEFAULT_AVOIDANCE = Avoidance()  # K_avoid = 4 m^2/s, peer radius 1 m


def tick(
    pose: Sequence[float],
    task: AgentTask | None,
    peers: FloatArray = NO_PEERS,
    obstacles: tuple[FloatArray, FloatArray] = NO_OBSTACLES,
    age: float = 0.0,
    avoidance: Avoidance = DEFAULT_AVOIDANCE,
    now: float = 0.0,
    safety: SafetyConfig | None = None,
) -> TickResult:
    """One tick with peers at ``peers`` (M, 2); the safety filter only with ``safety``."""
    return decide(
        pose, age, task, bodies(peers), obstacles, PROFILE, avoidance, 0.5, now=now,
        safety=safety, period=0.02,
    )  # fmt: skip


# -- task protocol -----------------------------------------------------------------------
def test_new_task_replaces_and_repeat_is_ignored() -> None:
    t1 = apply_assignment(None, park("t1"))
    assert t1 is not None and t1.task_id == "t1" and t1.status is AgentTaskStatus.ACTIVE
    arrived = AgentTask(t1.assignment, AgentTaskStatus.ARRIVED)
    assert apply_assignment(arrived, park("t1", goal=(9.0, 9.0, 0.0))) is arrived
    t2 = apply_assignment(arrived, park("t2"))
    assert t2 is not None and t2.task_id == "t2" and t2.status is AgentTaskStatus.ACTIVE


def test_cancel_only_affects_the_current_task() -> None:
    t1 = apply_assignment(None, park("t1"))
    assert apply_assignment(t1, CancelAssignment(robot_id="r1", task_id="other")) is t1
    assert apply_assignment(None, CancelAssignment(robot_id="r1", task_id="t1")) is None
    cancelled = apply_assignment(t1, CancelAssignment(robot_id="r1", task_id="t1"))
    assert cancelled is not None and cancelled.status is AgentTaskStatus.CANCELLED
    assert cancelled.task_id == "t1"
    # a late repeat of the cancelled task does not restart it
    assert apply_assignment(cancelled, park("t1")) is cancelled


def test_higher_revision_replaces_the_law_and_stale_revisions_are_ignored() -> None:
    t1 = apply_assignment(None, park("t1", law="ccw"))
    assert t1 is not None and t1.assignment.revision == 0
    r1 = apply_assignment(t1, park("t1", law="cw", revision=1))
    assert r1 is not None and r1.task_id == "t1" and r1.status is AgentTaskStatus.ACTIVE
    assert r1.assignment.law == "cw" and r1.assignment.revision == 1
    # late duplicates of revision 0 or 1 change nothing
    assert apply_assignment(r1, park("t1", law="ccw")) is r1
    assert apply_assignment(r1, park("t1", law="ccw", revision=1)) is r1
    # the robot drives on with the new law: omega <= 0 for cw (Eq. 20)
    assert tick((0.0, 1.0, 0.0), r1).omega <= 0.0
    r2 = apply_assignment(r1, park("t1", law="ccw", revision=2))
    assert r2 is not None and r2.assignment.law == "ccw"
    assert tick((0.0, 1.0, 0.0), r2).omega >= 0.0


def test_a_revision_keeps_an_arrived_or_cancelled_task_stopped() -> None:
    t1 = apply_assignment(None, park("t1"))
    assert t1 is not None
    for status in (AgentTaskStatus.ARRIVED, AgentTaskStatus.CANCELLED):
        stopped = AgentTask(t1.assignment, status)
        revised = apply_assignment(stopped, park("t1", law="cw", revision=1))
        assert revised is not None and revised.status is status
        assert not tick((0.0, 1.0, 0.0), revised).moving


def test_revision_must_not_be_negative() -> None:
    with pytest.raises(ValueError):
        park("t1", revision=-1)


# -- modes -------------------------------------------------------------------------------
def test_no_task_is_idle_and_still() -> None:
    d = tick((0.0, 0.0, 0.0), None)
    assert d.mode is RobotMode.IDLE and d.task is None and not d.moving


def test_active_task_drives_towards_goal() -> None:
    d = tick((0.0, 0.0, 0.0), AgentTask(park()))
    assert d.mode is RobotMode.DRIVING and d.u > 0 and d.right > 0 and d.left > 0


def test_cancelled_task_holds_still() -> None:
    d = tick((0.0, 0.0, 0.0), AgentTask(park(), AgentTaskStatus.CANCELLED))
    assert d.mode is RobotMode.HOLDING and not d.moving and d.task is not None


@pytest.mark.parametrize("age", [0.51, 10.0, math.inf, math.nan])
def test_stale_pose_stops_the_robot(age: float) -> None:
    task = AgentTask(park())
    d = tick((0.0, 0.0, 0.0), task, age=age)
    assert d.mode is RobotMode.HOLDING and not d.moving
    assert d.task is task  # resumes when the pose is fresh again
    assert tick((0.0, 0.0, 0.0), task, age=0.49).mode is RobotMode.DRIVING


def test_arrival_uses_the_pre_step_tolerance_applies_that_step_and_latches() -> None:
    task = AgentTask(park(goal=(1.0, 1.0, 0.5)))
    inside = (1.0 + 0.07, 1.0 - 0.05, 0.5 - 0.09)  # 0.086 m < 0.1, 0.09 rad < 0.1
    assert within_tolerance(inside, task.assignment)
    d = tick(inside, task)
    assert d.mode is RobotMode.ARRIVED
    assert d.task is not None and d.task.status is AgentTaskStatus.ARRIVED
    # the stop rule's step is still applied, as in the batch simulator and the paper
    expected = reference.step(inside, (1.0, 1.0, 0.5), TEST_GAINS.as_tuple(), False, 0.02)
    assert (d.u, d.omega) == (expected.u, expected.omega)
    # latched: the next tick stops; even pushed outside the tolerance it stays arrived
    after = tick((0.0, 0.0, 0.0), d.task)
    assert after.mode is RobotMode.ARRIVED and not after.moving


def test_heading_outside_tolerance_is_not_arrived() -> None:
    task = AgentTask(park(goal=(1.0, 1.0, 0.5)))
    assert tick((1.0, 1.0, 0.5 - 0.11), task).mode is RobotMode.DRIVING


# -- avoidance (Eq. 27) ------------------------------------------------------------------
PAPERS_TERM = Avoidance(smoothing_m=0.0)  # Eq. (27) as the paper writes it


def test_peer_ahead_inside_radius_slows_the_robot_and_sets_avoiding() -> None:
    task = AgentTask(park(avoidance=PAPERS_TERM))
    free = tick((0.0, 0.0, 0.0), task)
    peer_ahead = np.array([[0.5, 0.0]])
    blocked = tick((0.0, 0.0, 0.0), task, peers=peer_ahead)
    assert blocked.mode is RobotMode.AVOIDING
    assert blocked.repulsion == pytest.approx(-4.0 / 0.5)  # -K_avoid / x_OA
    assert blocked.u < free.u
    smoothed = tick((0.0, 0.0, 0.0), AgentTask(park()), peers=peer_ahead)  # the fleet's default
    w = DEFAULT_AVOIDANCE.smoothing_m  # linear in x_OA within w of abeam, faded in over w
    term = -4.0 * 0.5 / w**2 if w > 0.5 else -4.0 / 0.5
    assert smoothed.repulsion == pytest.approx(min(1.0, (1.0 - 0.5) / w) * term)
    assert smoothed.mode is RobotMode.AVOIDING and smoothed.u < free.u


def test_peer_outside_radius_changes_nothing() -> None:
    task = AgentTask(park())
    free = tick((0.0, 0.0, 0.0), task)
    far = tick((0.0, 0.0, 0.0), task, peers=np.array([[1.01, 0.0], [-5.0, 3.0]]))
    assert far.mode is RobotMode.DRIVING and far == free


def test_static_obstacle_uses_its_own_radius() -> None:
    task = AgentTask(park(avoidance=PAPERS_TERM))
    obstacles = obstacle_arrays([Obstacle(x=1.5, y=0.0, radius=2.0)])
    d = tick((0.0, 0.0, 0.0), task, obstacles=obstacles)
    assert d.mode is RobotMode.AVOIDING and d.repulsion == pytest.approx(-4.0 / 1.5)
    small = obstacle_arrays([Obstacle(x=1.5, y=0.0, radius=1.0)])
    assert tick((0.0, 0.0, 0.0), task, obstacles=small).mode is RobotMode.DRIVING


def test_robot_avoidance_settings_apply_unless_the_assignment_sets_them() -> None:
    peer = np.array([[1.5, 0.0]])
    wide = Avoidance(peer_radius=2.0)
    assert tick((0, 0, 0), AgentTask(park()), peers=peer, avoidance=wide).mode is RobotMode.AVOIDING
    explicit = AgentTask(park(avoidance=Avoidance(peer_radius=1.0)))
    assert tick((0, 0, 0), explicit, peers=peer, avoidance=wide).mode is RobotMode.DRIVING
    off = Avoidance(k_avoid=0.0, peer_radius=2.0)
    assert tick((0, 0, 0), AgentTask(park()), peers=peer, avoidance=off).mode is RobotMode.DRIVING


# -- wheel-speed limit -------------------------------------------------------------------
coord = st.floats(-8, 8, allow_nan=False)
angle = st.floats(-7, 7, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(
    pose=st.tuples(coord, coord, angle),
    goal=st.tuples(coord, coord, angle),
    law=st.sampled_from(["ccw", "cw"]),
    peers=st.lists(st.tuples(coord, coord), max_size=5),
    limit=st.one_of(st.none(), st.floats(0.5, 40)),
)
def test_wheel_speeds_never_exceed_the_limit_and_keep_the_curvature(
    pose: tuple[float, float, float],
    goal: tuple[float, float, float],
    law: str,
    peers: list[tuple[float, float]],
    limit: float | None,
) -> None:
    task = AgentTask(park(goal=goal, law=law, max_wheel_speed=limit))
    d = tick(pose, task, peers=np.array(peers, dtype=float).reshape(-1, 2))
    cap = PROFILE.max_wheel_speed if limit is None else min(limit, PROFILE.max_wheel_speed)
    assert max(abs(d.right), abs(d.left)) <= cap * (1 + 1e-9)
    # Eq. (2): the wheel speeds reproduce (u, omega)
    r, b = PROFILE.wheel_radius, PROFILE.half_axle
    assert r / 2 * (d.right + d.left) == pytest.approx(d.u, abs=1e-9)
    assert r / (2 * b) * (d.right - d.left) == pytest.approx(d.omega, abs=1e-9)
    if d.mode is not RobotMode.ARRIVED:
        assert (d.omega >= 0) if law == "ccw" else (d.omega <= 0)


# -- link loss and contact guard ---------------------------------------------------------
def test_lost_link_holds_the_task_and_resumes_when_it_returns() -> None:
    task = AgentTask(park())
    blind = decide(
        (0.0, 0.0, 0.0),
        0.0,
        task,
        bodies(NO_PEERS),
        NO_OBSTACLES,
        PROFILE,
        DEFAULT_AVOIDANCE,
        0.5,
        link_ok=False,
    )
    assert blind.mode is RobotMode.HOLDING and not blind.moving and blind.task == task
    back = decide(
        (0.0, 0.0, 0.0),
        0.0,
        task,
        bodies(NO_PEERS),
        NO_OBSTACLES,
        PROFILE,
        DEFAULT_AVOIDANCE,
        0.5,
        link_ok=True,
    )
    assert back.mode is RobotMode.DRIVING and back.u > 0


@pytest.mark.parametrize(
    ("now", "last_heard", "router", "up"),
    [(10.0, 9.0, True, True), (10.0, 6.0, True, False), (10.0, 9.9, False, False)],
)
def test_link_rule_needs_a_router_and_recent_traffic(
    now: float, last_heard: float, router: bool, up: bool
) -> None:
    assert link_is_up(now, last_heard, router, timeout_s=3.0) is up


@settings(max_examples=200)
@given(
    st.floats(-math.pi, math.pi),
    st.floats(0.0, 2 * math.pi),
    st.floats(0.05, 0.6),
    st.tuples(st.floats(-4, 4), st.floats(-4, 4), st.floats(-math.pi, math.pi)),
)
def test_the_filter_never_drives_a_robot_into_a_peer_at_the_margin(
    heading: float, bearing: float, distance: float, goal: tuple[float, float, float]
) -> None:
    """Within the margin (2 radii + 5 cm plus the projection and spreads) of a peer, the
    robot's projected point never gets closer to the peer's, whatever the law pulls to.

    A weak repulsion (a small configured K_avoid) lets the law's pull win at short range:
    that is when only the filter keeps the bodies apart.
    """
    peer = np.array([[distance * math.cos(bearing), distance * math.sin(bearing)]])
    weak = Avoidance(k_avoid=0.05)
    decision = tick(
        (0.0, 0.0, heading), AgentTask(park(goal=goal)), peers=peer, avoidance=weak, safety=SAFETY
    )
    ahead = SAFETY.projection_m
    point = (ahead * math.cos(heading), ahead * math.sin(heading))
    target = (peer[0, 0] + ahead, peer[0, 1])  # the peer's projected point (heading 0)
    moved = (
        point[0]
        + 0.02 * (decision.u * math.cos(heading) - ahead * decision.omega * math.sin(heading)),
        point[1]
        + 0.02 * (decision.u * math.sin(heading) + ahead * decision.omega * math.cos(heading)),
    )
    gap = math.dist(point, target) - 2 * (0.2 + ahead) - SAFETY.contact_margin_m
    # the filter's bound is <= 0 within the own spread (the peers here have none)
    if gap <= SAFETY.own_spread(0.0):
        assert math.dist(moved, target) >= math.dist(point, target) - 1e-12


def test_the_filter_leaves_a_robot_free_far_from_every_body() -> None:
    peer = np.array([[0.5, 0.8]])  # ahead to the left, inside the 1 m influence zone
    decision = tick(
        (0.0, 0.0, 0.0), AgentTask(park(goal=(9.0, 0.0, 0.0))), peers=peer, safety=SAFETY
    )
    assert decision.mode is RobotMode.AVOIDING
    # Eq. (17) u = 9 m/s plus Eq. (27) -4/0.5 m/s is still forward, and the wheel limit
    # caps it at r * max_wheel_speed; the filter lets it be (it closes on the peer at
    # 0.53 m/s, well within what the clearance allows).
    far = tick((0.0, 0.0, 0.0), AgentTask(park(goal=(9.0, 0.0, 0.0))), peers=peer)
    assert decision.u == far.u == pytest.approx(PROFILE.max_speed)


def test_an_obstacle_body_stops_a_robot_the_influence_radius_would_not() -> None:
    """A post with a body on the straight line to the goal and no repulsion: the filter
    turns or stops the robot before its body reaches the post's; without it, it drives on."""
    post = obstacle_arrays([Obstacle(x=0.6, y=0.0, radius=0.3, body=0.3)])
    off = Avoidance(k_avoid=0.0)
    task = AgentTask(park(goal=(3.0, 0.0, 0.0)))
    free = tick((0.0, 0.0, 0.0), task, obstacles=post, avoidance=off)
    held = tick((0.0, 0.0, 0.0), task, obstacles=post, avoidance=off, safety=SAFETY)
    assert free.u == pytest.approx(PROFILE.max_speed)
    assert held.u < 0.25 * free.u and held.mode is RobotMode.AVOIDING


def test_start_delay_waits_then_drives_and_a_revision_restarts_it() -> None:
    task = apply_assignment(None, park(start_delay_s=1.0), now=10.0)
    assert task is not None and task.applied_at == 10.0
    for now, mode in ((10.0, RobotMode.WAITING), (10.98, RobotMode.WAITING)):
        d = tick((0.0, 0.0, 0.0), task, now=now)
        assert d.mode is mode and not d.moving and d.task == task
    d = tick((0.0, 0.0, 0.0), task, now=11.0)
    assert d.mode is RobotMode.DRIVING and d.moving
    revised = apply_assignment(task, park(start_delay_s=0.5, revision=1), now=20.0)
    assert revised is not None and revised.applied_at == 20.0
    assert tick((0.0, 0.0, 0.0), revised, now=20.2).mode is RobotMode.WAITING
    assert tick((0.0, 0.0, 0.0), revised, now=20.5).moving


def test_hold_stands_still_until_a_revision_releases_it() -> None:
    held = apply_assignment(None, park(hold=True), now=0.0)
    assert held is not None
    d = tick((0.0, 0.0, 0.0), held, now=1e6)
    assert d.mode is RobotMode.WAITING and not d.moving
    assert apply_assignment(held, park(hold=False), now=5.0) is held  # same revision: ignored
    released = apply_assignment(held, park(hold=False, revision=1), now=5.0)
    assert tick((0.0, 0.0, 0.0), released, now=5.0).moving


def test_a_waiting_robot_already_at_its_goal_reports_arrived() -> None:
    task = apply_assignment(None, park(goal=(0.0, 0.0, 0.0), start_delay_s=5.0), now=0.0)
    assert tick((0.0, 0.0, 0.0), task, now=0.0).mode is RobotMode.ARRIVED


def test_the_control_step_is_compiled_at_import_and_ticks_never_compile() -> None:
    """``robot_agent.logic`` imports the compiled step with explicit signatures: compiled (or
    loaded from numba's cache) before any tick, and frozen -- a tick cannot compile."""
    from fleet.core import step

    entry = step._step_robot
    assert len(entry.signatures) == 1 and not entry._can_compile
    obstacles = obstacle_arrays([Obstacle(x=1.0, y=0.2, radius=1.0)])
    for peers in (NO_PEERS, np.array([[0.3, 0.0], [2.0, 2.0]])):
        tick((0.0, 0.0, 0.0), AgentTask(park()), peers=peers, obstacles=obstacles)
    assert len(entry.signatures) == 1
