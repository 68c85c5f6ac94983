"""Routes: via-points passed without stopping, the same in the agent's tick and the batch."""

from __future__ import annotations

import math

import numpy as np
import pytest
import support
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from fleet.core import step
from fleet.core.params import RobotProfile, SafetyConfig
from fleet.core.route import remaining, route_table
from fleet.core.simulate import BatchProblem, batch_filter, obstacle_columns, simulate
from fleet.core.tasks import DEFAULT_GAINS
from fleet.core.types import Law, Posture
from fleet.core.wire import Obstacle, ParkAssignment, parse_assignment
from fleet.io.settings import load_settings
from robot_agent.logic import AgentTask, apply_assignment, decide, obstacle_arrays

PROFILE = RobotProfile(wheel_radius=0.05, half_axle=0.15, max_wheel_speed=10.0, radius=0.2)
DT = 0.02
#: A wall across the straight line from START to GOAL.
WALL = Obstacle(x=0.0, y=-1.5, end=(0.0, 1.5), radius=0.3, body=0.05)
START: Posture = (-3.0, 0.0, 0.0)
GOAL: Posture = (3.0, 0.0, 0.0)
#: Around the wall's lower end, then the pre-bay point in front of the goal.
AROUND = [(-0.8, -2.0), (0.8, -2.0), (2.0, 0.0)]


def assignment(points: list[tuple[float, float]], law: Law = "cw") -> ParkAssignment:
    return support.park(goal=GOAL, law=law, route=points, pass_m=0.5)


def agent_run(a: ParkAssignment, steps: int) -> tuple[list[Posture], bool]:
    """The agent's ticks on a perfect drive (the Euler step of the compiled step)."""
    task: AgentTask | None = apply_assignment(None, a)
    pose, poses, obstacles = START, [START], obstacle_arrays([WALL])
    no_peers = (np.zeros((3, 0)), np.zeros((2, 0)))
    for _ in range(steps):
        r = decide(
            pose, 0.0, task, no_peers, obstacles, PROFILE, a.avoidance, 1.0,
            safety=SafetyConfig(), period=DT,
        )  # fmt: skip
        task = r.task
        x, y, theta = pose
        pose = (
            x + math.cos(theta) * r.u * DT,
            y + math.sin(theta) * r.u * DT,
            theta + r.omega * DT,
        )
        poses.append(pose)
        if r.mode == "arrived":
            return poses, True
    return poses, False


def batch_run(a: ParkAssignment, steps: int) -> tuple[np.ndarray, bool]:
    problem = BatchProblem.build(
        [START], [GOAL], a.gains, a.law, a.tolerance, PROFILE, **obstacle_columns([WALL]),
        k_avoid=a.avoidance.k_avoid, min_x_oa=a.avoidance.min_x_oa,
        smoothing=a.avoidance.smoothing_m,
        safety=batch_filter(SafetyConfig()), routes=[a.route], pass_radius=a.pass_m,
    )  # fmt: skip
    result = simulate(problem, dt=DT, max_time=steps * DT, record=True)
    assert result.trajectory is not None
    return result.trajectory.poses[:, 0, :], bool(result.done[0])


@pytest.mark.parametrize("law", ["cw", "ccw"])
def test_the_agent_follows_its_route_exactly_as_the_planner_predicts(law: Law) -> None:
    a = assignment(AROUND, law)
    poses, arrived = agent_run(a, 6000)
    predicted, done = batch_run(a, 6000)
    assert arrived and done
    assert np.array_equal(np.array(poses), predicted)  # bit for bit


def test_a_wall_stops_a_robot_without_a_route_and_a_route_takes_it_around() -> None:
    straight, arrived = agent_run(support.park(goal=GOAL, law="cw"), 3000)
    assert not arrived
    assert straight[-1][0] < 0.0  # stopped on its side of the wall
    around, arrived = agent_run(assignment(AROUND), 6000)
    assert arrived
    clearance = min(WALL.distance(x, y) for x, y, _ in around) - WALL.body_radius
    assert clearance >= PROFILE.radius  # never touched the wall
    # Passed every via-point on the way, without stopping (it never stood still).
    for vx, vy in AROUND:
        assert min(math.hypot(x - vx, y - vy) for x, y, _ in around) < 0.5
    steps = np.diff(np.array(around)[:-1, :2], axis=0)
    assert (np.hypot(steps[:, 0], steps[:, 1]) > 0).all()


def test_a_revision_replaces_the_route_from_its_first_via_point() -> None:
    a = assignment(AROUND)
    task = apply_assignment(None, a)
    assert task is not None
    no_peers = (np.zeros((3, 0)), np.zeros((2, 0)))
    near_first = (-0.8, -1.8, 0.0)
    r = decide(near_first, 0.0, task, no_peers, obstacle_arrays([]), PROFILE, a.avoidance, 1.0)
    assert r.task is not None and r.task.leg == 1  # passed the first via-point
    revised = a.model_copy(update={"revision": 1})
    again = apply_assignment(r.task, revised)
    assert again is not None and again.leg == 0 and again.assignment.revision == 1


@settings(max_examples=300, deadline=None)
@given(
    st.tuples(st.floats(-10, 10), st.floats(-10, 10), st.floats(-math.pi, math.pi)),
    st.tuples(st.floats(-10, 10), st.floats(-10, 10)),
    st.tuples(st.floats(0.1, 5), st.floats(0.1, 5), st.floats(0.1, 5)),
    st.sampled_from([0.5, 5.0, math.inf]),
)
def test_a_step_never_takes_a_robot_farther_from_the_via_point_it_aims_at(
    pose: Posture, via: tuple[float, float], gains: tuple[float, float, float], limit: float
) -> None:
    """Both laws command u = kx x_e: one Euler step changes the squared distance by
    -kx x_e^2 dt (2 - kx dt) (times the saturation factor), never more (kx dt <= 2)."""
    assume(math.hypot(via[0] - pose[0], via[1] - pose[1]) > 0.6)  # beyond the pass radius
    table = route_table([via], GOAL, cw=False)
    params = step.robot_params(
        np.array([GOAL]), np.array([gains]), np.zeros(1), np.full(1, 0.1), np.full(1, 0.1),
        np.full(1, 0.05), np.full(1, 0.15), np.full(1, limit), np.full(1, 0.2),
        route_last=np.ones(1), pass_radius=0.5,
    )  # fmt: skip
    assert step.aim(*pose, params, table, 0, obstacle_arrays([])) == 0
    assert (params[0, step.GOAL_X], params[0, step.GOAL_Y]) == via
    r = step.step_robot(
        pose, params, peers=np.zeros((3, 0)), shapes=np.zeros((2, 0)),
        obstacles=obstacle_arrays([]), k_avoid=0.0, peer_radius=0.0, min_x_oa=0.1, dt=DT,
    )  # fmt: skip
    before = math.hypot(via[0] - pose[0], via[1] - pose[1])
    after = math.hypot(via[0] - r.x, via[1] - r.y)
    assert after <= before + 1e-9
    # it faces the via-point with the law that turns the shorter way
    dx, dy = via[0] - pose[0], via[1] - pose[1]
    y_e = math.cos(pose[2]) * dy - math.sin(pose[2]) * dx  # the via-point's side, Eq. (5)
    assert (params[0, step.CW] == 1.0) == (y_e < 0)
    facing = params[0, step.GOAL_HEADING] - math.atan2(dy, dx)
    assert (
        math.cos(facing) == pytest.approx(1.0) and 0 <= params[0, step.GOAL_HEADING] < 2 * math.pi
    )
    assert r.omega * (1 if params[0, step.CW] == 0.0 else -1) >= 0.0


def test_an_assignment_without_a_route_is_the_one_of_before_and_pass_m_is_checked() -> None:
    old = support.park(goal=GOAL)
    parsed = parse_assignment(old.model_dump_json(exclude={"route", "pass_m"}).encode())
    assert isinstance(parsed, ParkAssignment) and parsed.route == []
    with pytest.raises(ValidationError, match="pass_m"):
        support.park(goal=GOAL, route=[(0.0, 0.0)], pass_m=0.05)


def test_the_rest_of_a_route_starts_at_the_leg_the_robot_is_on() -> None:
    assert remaining(AROUND, *START[:2]).tolist() == [list(p) for p in AROUND]
    assert remaining(AROUND, 0.0, -2.1).tolist() == [list(p) for p in AROUND[1:]]
    assert remaining(AROUND, 1.6, -0.8).tolist() == [list(AROUND[2])]
    assert remaining([], 0.0, 0.0).shape == (0, 2)


def test_a_robot_past_the_last_via_point_has_none_left_only_when_the_goal_is_given() -> None:
    past = (2.5, 0.05)  # between the pre-bay point (2, 0) and the goal (3, 0)
    assert remaining(AROUND, *past).tolist() == [list(AROUND[2])]  # without the goal
    assert remaining(AROUND, *past, GOAL[:2]).shape == (0, 2)
    # still short of the pre-bay point, or nearer another leg: the route goes on
    assert remaining(AROUND, 1.6, -0.8, GOAL[:2]).tolist() == [list(AROUND[2])]
    assert remaining(AROUND, 0.0, -2.1, GOAL[:2]).tolist() == [list(p) for p in AROUND[1:]]
    # beside the goal but nearer the leg before the last: not on the last leg
    assert remaining(AROUND, 2.5, -1.6, GOAL[:2]).tolist() == [list(AROUND[2])]


def test_a_via_point_is_passed_early_only_where_the_next_leg_clears_the_corner() -> None:
    table = route_table([(0.0, 2.1), (1.5, 0.0)], GOAL, cw=False)
    params = step.robot_params(
        np.array([GOAL]), np.array([(1.0, 1.0, 1.0)]), np.zeros(1), np.full(1, 0.1),
        np.full(1, 0.1), np.full(1, 0.05), np.full(1, 0.15), np.full(1, 10.0), np.full(1, 0.2),
        route_last=np.full(1, 2.0), pass_radius=0.5,
    )  # fmt: skip
    wall = obstacle_arrays([WALL])
    # within the pass radius, but the straight way on would graze the wall's upper end
    assert step.aim(-0.4, 2.0, 0.0, params, table, 0, wall) == 0
    assert step.aim(-0.4, 2.0, 0.0, params, table, 0, obstacle_arrays([])) == 1
    # past the corner the next leg is clear: passed without reaching the via-point
    assert step.aim(0.3, 2.05, 0.0, params, table, 0, wall) == 1
    # within half the pass radius it is passed anyway (peers may crowd the corner)
    assert step.aim(-0.2, 2.0, 0.0, params, table, 0, wall) == 1


@pytest.mark.parametrize("law", ["cw", "ccw"])
@pytest.mark.parametrize("beside", [-0.5, -0.3, 0.3, 0.5])
@pytest.mark.parametrize("along", [1.0, 1.5])
def test_a_robot_routed_past_a_standing_peer_goes_round_it_and_arrives(
    law: Law, beside: float, along: float
) -> None:
    """A via-point 3 m dead ahead, a standing peer ``along`` m down the leg and ``beside``
    m to its side, the planner's model with the default bounds: the filter's sideways aim
    takes the robot round the peer on the side away from it, and it arrives. With the side
    of the law facing the via-point (the shorter way, flipping as the via-point crosses
    dead ahead) it turned back and forth 0.8 m from the peer until the end of the run:
    360-390 reversals of omega in 20 s, never arriving (docs/benchmarks.md)."""
    defaults = load_settings()
    avoidance = defaults.avoidance
    peer = (along, beside, 1.0)
    problem = BatchProblem.build(
        [(0.0, 0.0, 0.0), peer], [(4.5, 0.0, 0.0), peer],
        [DEFAULT_GAINS[law], DEFAULT_GAINS["ccw"]], [law, "ccw"], profile=defaults.profile,
        k_avoid=avoidance.k_avoid, peer_radius=avoidance.peer_radius,
        min_x_oa=avoidance.min_x_oa, smoothing=avoidance.smoothing_m,
        safety=batch_filter(defaults.safety), start_delay=[0.0, math.inf],
        routes=[np.array([(3.0, 0.0)]), None], pass_radius=0.5,
    )  # fmt: skip
    result = simulate(problem, dt=DT, max_time=20.0, record=True)
    assert result.trajectory is not None and result.done[0]
    poses = result.trajectory.poses[:, 0, :]
    abreast = poses[np.abs(poses[:, 0] - along) < 0.1]
    assert len(abreast) and (abreast[:, 1] * beside < 0.0).all()  # round the far side
