"""Lanes: routes follow them in their direction, get on and off near the robot and its bay,
fall back to the free space's route graph where the lanes give no way; bad lanes are
site problems; the planner sends the lanes' way."""

from __future__ import annotations

import itertools
import math

import pytest
from planning import idle, queued
from pydantic import ValidationError

from fleet.core.geometry import segment_distance
from fleet.core.params import Avoidance
from fleet.core.planner import PlanningSnapshot, TaskDecision, plan
from fleet.core.planner.lanes import route_graph
from fleet.core.planner.roadmap import roadmap_of
from fleet.core.route import lane_shapes
from fleet.core.site import Lane, Site, Wall, Yard
from fleet.core.wire import Obstacle

CLEARANCE = 0.4
WALL = tuple(Wall(points=[(-2, 0), (2, 0)], body=0.05).segments())  # across the middle
LOOP = [Lane(points=[(-4, -2), (4, -2), (4, 2), (-4, 2), (-4, -2)], one_way=True)]  # ccw


def test_a_one_way_loop_sends_robots_round_the_wall_with_its_flow_both_ways() -> None:
    graph = route_graph(WALL, CLEARANCE, lane_shapes(LOOP))
    north = graph.route((0.0, -1.0), (0.0, 1.0, math.pi / 2), 1.0)
    south = graph.route((0.0, 1.0), (0.0, -1.0, -math.pi / 2), 1.0)
    assert north is not None and south is not None
    assert all(x > 3.9 for x, _ in north)  # the east side goes north
    assert [y for _, y in north] == sorted(y for _, y in north)
    assert all(x < -3.9 for x, _ in south)  # the west side goes south
    assert [y for _, y in south] == sorted((y for _, y in south), reverse=True)


def test_a_two_way_lane_is_driven_either_way_and_the_free_graph_is_not_used() -> None:
    both = [Lane(points=[(-4, -2), (4, -2), (4, 2), (-4, 2), (-4, -2)])]
    graph = route_graph(WALL, CLEARANCE, lane_shapes(both))
    south = graph.route((0.0, 1.0), (0.0, -1.0, -math.pi / 2), 1.0)
    assert south is not None and all(abs(x) > 3.9 for x, _ in south)  # round the lane's side
    free = roadmap_of(WALL, CLEARANCE).route((0.0, 1.0), (0.0, -1.0, -math.pi / 2), 1.0)
    assert free is not None and all(abs(x) < 3.0 for x, _ in free)  # round the wall's end


def test_open_floor_to_the_goal_is_driven_straight_lanes_or_not() -> None:
    graph = route_graph(WALL, CLEARANCE, lane_shapes(LOOP))
    assert graph.route((0.0, -1.0), (1.0, -1.2, 0.0), 1.0) == ()
    assert graph.route((-3.0, -1.0), (3.0, -1.0, 0.0), 1.0) == ()  # beside the wall, clear


def test_where_no_lane_is_seen_the_free_route_graph_leads() -> None:
    box = Wall(points=[(-6, 3), (6, 3), (6, 6), (-6, 6)], closed=True, body=0.05).segments()
    walls = (*WALL, *box)
    lanes = [Lane(points=[(-5, 4.5), (5, 4.5)])]  # inside the closed box: no robot sees it
    graph = route_graph(walls, CLEARANCE, lane_shapes(lanes))
    start, goal = (0.0, -1.0), (0.0, 1.0, math.pi / 2)
    assert graph.route(start, goal, 1.0) == roadmap_of(walls, CLEARANCE).route(start, goal, 1.0)


def test_lanes_through_a_wall_or_with_an_empty_leg_are_refused() -> None:
    site = Site(
        yard=Yard(xmin=-10, xmax=10, ymin=-10, ymax=10),
        walls=[Wall(name="middle", points=[(-2, 0), (2, 0)])],
        lanes=[Lane(name="through", points=[(0, -3), (0, 3)]), Lane(points=[(-5, 5), (5, 5)])],
    )
    (problem,) = site.problems(robot_radius=0.2, peer_radius=1.0)
    assert str(problem).startswith(
        "lane through: the leg from point 0 to point 1 passes 0.00 m from the body"
    )
    assert problem.loc == ("lanes", 0, "points", 0)
    with pytest.raises(ValidationError, match="point 1 repeats point 0"):
        Lane(points=[(0, 0), (0, 0), (1, 1)])


def test_the_planner_sends_the_lanes_way() -> None:
    snapshot = PlanningSnapshot(
        version=1,
        robots=(idle("r0", (0.0, -1.0, 0.0)),),
        tasks=(queued("t0", (0.0, 1.2, math.pi / 2), "r0"),),
        obstacles=WALL,
        lanes=lane_shapes(LOOP),
        control_dt=0.05,
    )
    (decision,) = plan(snapshot).decisions
    assert decision.route and all(x > 3.9 for x, _ in decision.route[:-1])


@pytest.mark.parametrize("one_way", [True, False], ids=["one-way", "two-way"])
def test_a_robot_standing_on_the_lanes_way_is_driven_round(one_way: bool) -> None:
    """An idle robot on the lane point the route turns at: the robot could never reach that
    via-point (Eq. (27) holds it off), so the route goes round the standing robot."""
    lanes = lane_shapes([Lane(points=LOOP[0].points, one_way=one_way)])
    task = queued("t0", (0.0, 1.2, math.pi / 2), "r0")

    def decide(*others: tuple[float, float]) -> TaskDecision:
        robots = (idle("r0", (0.0, -1.0, 0.0)),)
        robots += tuple(idle(f"r{k + 1}", (*xy, 0.0)) for k, xy in enumerate(others))
        snapshot = PlanningSnapshot(
            version=1, robots=robots, tasks=(task,), obstacles=WALL, lanes=lanes, control_dt=0.05
        )
        (decision,) = plan(snapshot).decisions
        return decision

    alone = decide()
    assert (4.0, 0.0) in alone.route  # it turns on the lane at (4, 0)
    standing = (4.0, 0.0)
    decision = decide(standing)
    influence = Avoidance().peer_radius
    assert decision.route and all(math.dist(p, standing) > influence for p in decision.route)
    way = [(0.0, -1.0), *decision.route]
    assert all(segment_distance(*standing, a, b) > 0.45 for a, b in itertools.pairwise(way))
    assert decision.predicted_arrival_s is not None  # the planner sees it arrive


def test_a_wall_put_across_a_lane_closes_it() -> None:
    lane = [Lane(points=[(-4, -2), (-4, 2)]), Lane(points=[(4, -2), (4, 2)])]
    lanes = lane_shapes([*lane, Lane(points=[(-4, -2), (4, -2)]), Lane(points=[(-4, 2), (4, 2)])])
    start, goal = (0.0, -1.0), (0.0, 1.0, math.pi / 2)
    east = route_graph(WALL, CLEARANCE, lanes).route(start, goal, 1.0)
    assert east is not None
    side = 1.0 if max(x for x, _ in east) > 3.9 else -1.0
    block = Wall(points=[(side * 3.0, 0.0), (side * 5.0, 0.0)], body=0.05).segments()
    other = route_graph((*WALL, *block), CLEARANCE, lanes).route(start, goal, 1.0)
    assert other is not None and all(x * side < 0 for x, _ in other if abs(x) > 3.9)


def test_lanes_beside_a_lone_post_are_driven_as_drawn() -> None:
    """A one-way loop whose east side runs 1 m from a lone post, inside its Eq. (27) zone:
    the lanes are the operator's ways, so robots keep to the loop there; without lanes the
    way keeps clear of the zone."""
    pillar = (Obstacle(x=5.0, y=0.0, radius=1.5, body=0.3),)
    obstacles = (*WALL, *pillar)
    graph = route_graph(obstacles, CLEARANCE, lane_shapes(LOOP))
    north = graph.route((0.0, -1.0), (0.0, 1.0, math.pi / 2), 1.0)
    assert north is not None and any(math.isclose(x, 4.0) for x, _ in north)  # the loop's
    free = route_graph(pillar, CLEARANCE).route((5.0, -5.0), (5.0, 5.0, math.pi / 2), 1.0)
    assert free and min(math.hypot(x - 5.0, y) for x, y in free) >= 1.5 + CLEARANCE
