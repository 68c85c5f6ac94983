"""The route graph: routes keep the clearance, go around walls, through the gate, or fail.

Clearances are checked independently of shapely, with :mod:`fleet.core.geometry`.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st

from fleet.core.geometry import segments_cross, segments_distance
from fleet.core.planner.lanes import route_graph
from fleet.core.planner.roadmap import END_SLACK_M, Roadmap, roadmap_of, roundabouts
from fleet.core.site import Wall
from fleet.core.wire import Obstacle
from fleet.io.site_file import load_site

CARPARK = Path(__file__).resolve().parents[4] / "fleet" / "io" / "sites" / "carpark.toml"
CLEARANCE = 0.35  # [m] robot radius 0.2 + safety margin 0.1 + slack 0.05
Pt = tuple[float, float]


def wall(a: Pt, b: Pt, body: float = 0.1) -> Obstacle:
    return Obstacle(x=a[0], y=a[1], end=b, body=body, radius=max(body, 1.0))


def post(x: float, y: float, body: float = 0.1) -> Obstacle:
    return Obstacle(x=x, y=y, body=body, radius=max(body, 1.0))


def seg_distance(a: Pt, b: Pt, o: Obstacle) -> float:
    """Distance [m] between the segment a-b and the obstacle's segment."""
    return segments_distance(a, b, (o.x, o.y), o.far_end)


def own_clearance(point: Pt, obstacles: list[Obstacle], clearance: float) -> float:
    """The specified clearance of an end edge at ``point`` [m]."""
    nearest = min((o.distance(*point) - o.body_radius for o in obstacles), default=math.inf)
    return max(0.0, min(clearance, nearest - END_SLACK_M))


def pre_bay(goal: tuple[float, float, float], approach: float) -> Pt:
    return (goal[0] - approach * math.cos(goal[2]), goal[1] - approach * math.sin(goal[2]))


def legs(
    start: Pt, goal: tuple[float, float, float], approach: float, route: tuple[Pt, ...]
) -> list[tuple[Pt, Pt, list[Pt]]]:
    """Every leg a robot drives (its via-points, then the posture leg to the goal), each with
    the end points whose own clearance it may use."""
    g = (goal[0], goal[1])
    if not route:
        return [(start, g, [start, g])]
    p = pre_bay(goal, approach)
    to_p = approach > 0 and math.dist(route[-1], p) < 1e-9
    points = [start, *route]
    out = []
    for k, (a, b) in enumerate(itertools.pairwise(points)):
        ends = ([a] if k == 0 else []) + ([b] if to_p and k == len(points) - 2 else [])
        out.append((a, b, ends))
    out.append((route[-1], g, [g, route[-1]] if to_p else [g]))
    return out


def assert_keeps_clearance(
    obstacles: list[Obstacle],
    clearance: float,
    start: Pt,
    goal: tuple[float, float, float],
    approach: float,
    route: tuple[Pt, ...],
) -> None:
    for a, b, ends in legs(start, goal, approach, route):
        need = min([clearance] + [own_clearance(e, obstacles, clearance) for e in ends])
        for o in obstacles:
            gap = seg_distance(a, b, o) - o.body_radius
            assert gap >= need - 1e-9, (a, b, o, gap, need)


def length(start: Pt, route: tuple[Pt, ...], end: Pt) -> float:
    points = [start, *route, end]
    return sum(math.dist(a, b) for a, b in itertools.pairwise(points))


coord = st.floats(-5.0, 5.0)
posts = st.lists(st.builds(post, coord, coord, st.floats(0.0, 0.4)), max_size=10)
walls = st.lists(
    st.builds(wall, st.tuples(coord, coord), st.tuples(coord, coord), st.floats(0.05, 0.2)),
    max_size=6,
)


@settings(max_examples=150, deadline=None)
@given(
    posts,
    walls,
    st.floats(0.1, 0.5),
    st.tuples(st.floats(-6.0, -1.0), st.floats(-6.0, 6.0)),  # start and goal on either side
    st.tuples(st.floats(1.0, 6.0), st.floats(-6.0, 6.0), st.floats(-math.pi, math.pi)),
    st.floats(0.0, 1.5),
)
def test_every_leg_of_a_route_keeps_the_clearance(
    post_list: list[Obstacle],
    wall_list: list[Obstacle],
    clearance: float,
    start: Pt,
    goal: tuple[float, float, float],
    approach: float,
) -> None:
    obstacles = post_list + wall_list
    for point in (start, goal[:2]):  # start and goal anywhere outside the bodies
        assume(all(o.distance(*point) > o.body_radius + 0.02 for o in obstacles))
    roadmap = Roadmap.build(obstacles, clearance)
    route = roadmap.route(start, goal, approach)
    assert route == Roadmap.build(obstacles, clearance).route(start, goal, approach)
    for node in roadmap.nodes:  # every node is in free space
        assert all(o.distance(*node) - o.body_radius > clearance for o in obstacles)
    event("no route" if route is None else "straight" if not route else "via-points")
    if route is None:
        return
    assert_keeps_clearance(obstacles, clearance, start, goal, approach, route)
    if roadmap.free(start, goal[:2]):
        assert route == ()


@settings(max_examples=40, deadline=None)
@given(posts, walls, st.tuples(coord, coord), st.tuples(coord, coord))
def test_free_agrees_with_the_distances(
    post_list: list[Obstacle], wall_list: list[Obstacle], a: Pt, b: Pt
) -> None:
    obstacles = post_list + wall_list
    gaps = [seg_distance(a, b, o) - o.body_radius for o in obstacles]
    assume(all(abs(g - CLEARANCE) > 1e-6 for g in gaps))
    assert Roadmap.build(obstacles, CLEARANCE).free(a, b) == all(g > CLEARANCE for g in gaps)


# A wall across the straight line from START to the goal, its top end much nearer.
WALL = wall((0.0, -4.0), (0.0, 1.0))
START, GOAL, APPROACH = (-3.0, 0.0), (3.0, 0.0, 0.0), 1.0


def test_a_wall_in_the_way_is_driven_around_its_near_end() -> None:
    roadmap = Roadmap.build([WALL], CLEARANCE)
    route = roadmap.route(START, GOAL, APPROACH)
    assert route, "the wall blocks the straight line"
    assert route[-1] == pytest.approx(pre_bay(GOAL, APPROACH))
    assert_keeps_clearance([WALL], CLEARANCE, START, GOAL, APPROACH, route)
    # It crosses x = 0 above the top end, with the clearance: at least there, at most a bit on.
    top = 1.0 + WALL.body_radius + CLEARANCE
    p = pre_bay(GOAL, APPROACH)
    lower = math.dist(START, (0.0, top)) + math.dist((0.0, top), p)
    upper = math.dist(START, (0.0, top + 0.25)) + math.dist((0.0, top + 0.25), p)
    bottom = -4.0 - WALL.body_radius - CLEARANCE  # the way round the far end
    assert lower - 1e-9 <= length(START, route, p) <= upper
    assert upper < math.dist(START, (0.0, bottom)) + math.dist((0.0, bottom), p)
    assert max(y for _, y in route) >= top


def test_without_the_wall_the_route_is_straight() -> None:
    assert Roadmap.build([], CLEARANCE).route(START, GOAL, APPROACH) == ()
    aside = wall((0.0, 3.0), (0.0, 8.0))  # the same wall moved out of the way
    assert Roadmap.build([aside], CLEARANCE).route(START, GOAL, APPROACH) == ()


def test_a_goal_inside_a_closed_box_has_no_route() -> None:
    box = Wall(points=[(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)], closed=True)
    roadmap = Roadmap.build(box.segments(), CLEARANCE)
    assert roadmap.route((5.0, 0.0), (0.0, 0.0, 0.0), 1.0) is None
    assert roadmap.route((0.5, 0.5), (0.0, 0.0, 0.0), 1.0) == ()  # inside to inside


def test_a_blocked_pre_bay_point_routes_to_the_goal_itself() -> None:
    # The pre-bay point (1, 0) lies inside a short wall across the way to the goal.
    stub = wall((1.0, -0.6), (1.0, 0.6))
    goal = (2.0, 0.0, 0.0)
    route = Roadmap.build([stub], CLEARANCE).route(START, goal, 1.0)
    assert route, "the stub is in the way"
    assert all(math.dist(v, pre_bay(goal, 1.0)) > 0.5 for v in route)
    assert_keeps_clearance([stub], CLEARANCE, START, goal, 1.0, route)


def test_a_robot_closer_than_the_clearance_to_a_post_still_leaves_and_parks() -> None:
    # Start 0.25 m from a post's body (less than the clearance): only its own edges may
    # come that close. The goal is a tight bay between two posts, behind a wall.
    obstacles = [post(-3.0, 0.35), WALL, post(2.6, 0.0), post(3.4, 0.0)]
    roadmap = Roadmap.build(obstacles, CLEARANCE)
    start, goal = (-3.0, 0.0), (3.0, 0.0, math.pi / 2)  # bay 0.3 m from both posts' bodies
    assert not roadmap.free(start, (-3.0, -1.0))  # with the full clearance it could not
    route = roadmap.route(start, goal, 1.0)
    assert route and route[-1] == pytest.approx(pre_bay(goal, 1.0))
    assert_keeps_clearance(obstacles, CLEARANCE, start, goal, 1.0, route)


# Two rooms joined by a corridor 1.2 m wide along y = 0, its mouths at x = -4 and x = 4.
CORRIDOR = [
    wall((-4.0, 0.6), (4.0, 0.6)), wall((-4.0, -0.6), (4.0, -0.6)),
    wall((-4.0, 0.6), (-4.0, 5.0)), wall((-4.0, -0.6), (-4.0, -5.0)),
    wall((4.0, 0.6), (4.0, 5.0)), wall((4.0, -0.6), (4.0, -5.0)),
]  # fmt: skip


@settings(max_examples=200, deadline=None)
@given(st.floats(-3.9, 3.9), st.floats(-0.3, 0.3), st.booleans(), st.booleans())
def test_a_robot_in_a_corridor_is_routed_out_of_the_mouth_ahead_not_back(
    x: float, y: float, east: bool, north: bool
) -> None:
    """Off the corridor's centre line by up to 0.3 m -- where the roadmap's nodes, a margin
    beyond the clearance, no longer bound the free space -- a robot bound for a bay in
    either room leaves by the mouth on that side: no via-point behind it (the robot drove
    back to the mouth it had come in by, and met the robots following it)."""
    roadmap = Roadmap.build(CORRIDOR, CLEARANCE)
    goal = (8.5 if east else -8.5, 3.5 if north else -3.5, math.pi / 2 if north else -math.pi / 2)
    route = roadmap.route((x, y), goal, 1.0)
    assert route is not None
    assert all(vx >= x if east else vx <= x for vx, _ in route), route
    assert_keeps_clearance(CORRIDOR, CLEARANCE, (x, y), goal, 1.0, route)


def test_the_car_park_is_entered_through_the_gate() -> None:
    site = load_site(CARPARK)
    obstacles = site.static_obstacles()
    roadmap = Roadmap.build(obstacles, CLEARANCE)
    start = (-14.0, 5.0)  # outside the west wall, north of the gate
    for bay in site.bays:
        goal = (bay.pose.x, bay.pose.y, bay.pose.theta)
        route = roadmap.route(start, goal, 1.0)
        assert route is not None, bay.name
        if route:  # () when the straight line already passes the gate
            assert route[-1] == pytest.approx(pre_bay(goal, 1.0)), bay.name
        assert_keeps_clearance(obstacles, CLEARANCE, start, goal, 1.0, route)
        # It enters through the gate (x = -11.5, |y| < 2), kept clear of the gate's ends.
        half = 2.0 - 0.1 - CLEARANCE
        points = [start, *route] if route else [start, goal[:2]]
        assert any(
            segments_cross(a, b, (-11.5, -half), (-11.5, half))
            for a, b in itertools.pairwise(points)
        ), bay.name


def test_the_car_park_builds_small() -> None:
    roadmap = Roadmap.build(load_site(CARPARK).static_obstacles(), CLEARANCE)
    # 4 posts and 5 wall segments: about 8 nodes a post, not a polygon's 64.
    assert 20 <= len(roadmap.nodes) <= 100
    assert roadmap.graph.number_of_edges() > len(roadmap.nodes)


def test_build_refuses_absurd_sizes() -> None:
    grid = [post(3.0 * i, 3.0 * j) for i in range(30) for j in range(30)]  # 900 posts
    with pytest.raises(ValueError, match=r"nodes, more than 3000"):
        Roadmap.build(grid, CLEARANCE)
    with pytest.raises(ValueError, match=r"more than 10"):
        Roadmap.build(grid[:2], CLEARANCE, max_nodes=10)
    with pytest.raises(ValueError, match="clearance"):
        Roadmap.build(grid[:2], -1.0)
    with pytest.raises(ValueError, match="approach"):
        Roadmap.build(grid[:2], CLEARANCE).route((0.0, 0.0), (1.0, 1.0, 0.0), -1.0)


def test_a_point_is_a_segment_too() -> None:
    roadmap = Roadmap.build([WALL], CLEARANCE)
    assert not roadmap.free((0.2, 0.0), (0.2, 0.0))  # 0.1 m from the body
    assert roadmap.free((1.0, 0.0), (1.0, 0.0))
    assert roadmap.route((1.0, 0.0), (1.0, 0.0, 0.0), 1.0) == ()


def _turned(route: tuple[Pt, ...], start: Pt) -> float:
    """The angle [rad] a route's way (from ``start``) sweeps round the origin, + ccw."""
    points = [start, *route]
    angles = [math.atan2(y, x) for x, y in points]
    return sum(math.remainder(b - a, math.tau) for a, b in itertools.pairwise(angles))


@pytest.mark.parametrize("k", range(8))
def test_robots_crossing_a_ring_all_go_round_its_post_counter_clockwise(k: int) -> None:
    """Eight robots on a circle round a post, each to the antipodal point: both ways round
    are as long, and every route takes the counter-clockwise one (a roundabout: no two
    meet head-on beside the post)."""
    roadmap = Roadmap.build([post(0.0, 0.0, body=0.6)], CLEARANCE)
    bearing = k * math.tau / 8 + 0.01  # off the node grid's symmetry, either side
    start = (5.0 * math.cos(bearing), 5.0 * math.sin(bearing))
    goal = (-start[0], -start[1], bearing + math.pi)
    route = roadmap.route(start, goal, APPROACH)
    assert route
    assert _turned(route, start) > 0.0
    assert_keeps_clearance([post(0.0, 0.0, body=0.6)], CLEARANCE, start, goal, APPROACH, route)


def test_a_much_shorter_way_clockwise_round_a_post_is_still_taken() -> None:
    """The roundabout's price is on the arc hugging the post: a goal just past the post's
    clockwise side is reached that way."""
    roadmap = Roadmap.build([post(0.0, 0.0, body=0.6)], CLEARANCE)
    start, goal = (-3.0, 0.8), (3.0, 0.8, 0.0)
    route = roadmap.route(start, goal, APPROACH)
    assert route
    assert _turned(route, start) < 0.0
    assert min(y for _, y in route) > 0.0


def test_a_wall_of_posts_has_no_sense() -> None:
    """Posts whose grown bodies overlap make a wall: along it either way costs its length,
    so a robot takes the shorter side as with a wall segment."""
    row = [post(x, 0.0, body=0.25) for x in (-1.2, -0.6, 0.0, 0.6, 1.2)]
    roadmap = Roadmap.build(row, CLEARANCE)
    assert all(data["ccw_from"] < 0 for *_, data in roadmap.graph.edges(data=True)
               if "ccw_from" in data)  # fmt: skip
    alone = Roadmap.build([post(0.0, 0.0, body=0.25)], CLEARANCE)
    assert any(data.get("ccw_from", -1) >= 0 for *_, data in alone.graph.edges(data=True))


def test_a_gap_between_two_posts_is_driven_through_either_way() -> None:
    """The paper's case III pair (posts 1.6 m apart): a way through the gap passes one post
    clockwise whichever way it goes, so posts this close have no sense."""
    pair = [post(x, 0.0, body=0.2) for x in (-0.8, 0.8)]
    roadmap = Roadmap.build(pair, 0.4)
    assert all(data["ccw_from"] < 0 for *_, data in roadmap.graph.edges(data=True)
               if "ccw_from" in data)  # fmt: skip


@pytest.mark.parametrize("k", range(8))
def test_robots_crossing_a_ring_round_two_posts_no_robot_passes_between_go_counter_clockwise(
    k: int,
) -> None:
    """Two posts whose rings overlap (no way between them) are one island: robots crossing
    a ring round the pair go round it counter-clockwise (a roundabout round the pair's
    centre), as round one post; the posts themselves keep their bodies."""
    pair = (post(-0.6, 0.0, body=0.4), post(0.6, 0.0, body=0.4))
    roadmap = Roadmap.build(pair, CLEARANCE)
    assert [g.tolist() for g in roadmap.island_groups] == [[0, 1]]
    assert roundabouts(pair, CLEARANCE) is pair
    bearing = k * math.tau / 8 + 0.01
    start = (5.0 * math.cos(bearing), 5.0 * math.sin(bearing))
    goal = (-start[0], -start[1], bearing + math.pi)
    route = roadmap.route(start, goal, APPROACH)
    assert route and _turned(route, start) > 0.0
    assert_keeps_clearance(list(pair), CLEARANCE, start, goal, APPROACH, route)


def test_on_a_one_way_roadmap_a_shorter_way_clockwise_round_an_island_is_not_taken() -> None:
    """From beside one end of a pair of posts to beyond the other end's far side, the way
    clockwise along the near flank is much shorter: taken on the fleet's roadmap (a price
    of half its length), not on a one-way roadmap (the one a stuck recovery's robots are
    routed on), where the robot goes round counter-clockwise -- also from a start within
    a body's clearance, whose first leg need not be tangent to the outline."""
    pair = (post(-0.8, 0.0, body=0.85), post(0.8, 0.0, body=0.85))
    goal = (2.5, -1.2, 0.0)
    for start in ((-0.3, 1.4), (-0.3, 0.95)):  # outside the clearance, and within it
        fleet_way = roadmap_of(pair, CLEARANCE).route(start, goal, APPROACH)
        one_way = roadmap_of(pair, CLEARANCE, one_way=True).route(start, goal, APPROACH)
        assert fleet_way and _turned(fleet_way, start) < 0.0
        assert one_way and _turned(one_way, start) > 0.0
        assert_keeps_clearance(list(pair), CLEARANCE, start, goal, APPROACH, one_way)


def test_only_an_obstacle_standing_alone_grows_to_its_zone_for_routing() -> None:
    """A lone post's and a short lone wall segment's bodies grow to their Eq. (27)
    influence radii; a post of a pair, the segments of one wall (they touch), a long lone
    wall (a divider robots drive along, not round) and an obstacle whose body is its zone
    keep theirs; nothing grows: the same tuple."""
    alone = Obstacle(x=10.0, y=10.0, radius=1.2, body=0.6)
    short = wall((-10.0, -10.0), (-8.5, -10.0))  # body 0.1, zone 1.0
    pair = (post(-0.8, 0.0, body=0.2), post(0.8, 0.0, body=0.2))
    solid = Obstacle(x=-10.0, y=10.0, radius=0.5, body=0.5)
    corner = (wall((5.0, -10.0), (10.0, -10.0)), wall((10.0, -10.0), (10.0, -5.0)))
    divider = wall((20.0, 20.0), (29.0, 20.0))
    grown = roundabouts((alone, short, *pair, solid, *corner, divider), CLEARANCE)
    assert grown[0].body_radius == pytest.approx(1.2)
    assert grown[1].body_radius == pytest.approx(1.0)
    assert grown[2:] == (*pair, solid, *corner, divider)
    kept = (*pair, solid, *corner, divider)
    assert roundabouts(kept, CLEARANCE) is kept
    edges = Roadmap.build([divider], CLEARANCE).graph.edges(data=True)
    assert all(d["ccw_from"] < 0 for *_, d in edges if "ccw_from" in d)


@pytest.mark.parametrize("k", range(4))
def test_routes_round_a_lone_wall_go_counter_clockwise_outside_its_zone(k: int) -> None:
    """Robots crossing a ring round a short wall segment go round it counter-clockwise
    (a roundabout round its centre), every via-point the clearance outside its zone."""
    segment = wall((-0.8, 0.0), (0.8, 0.0), body=0.2)  # zone 1.0
    bearing = k * math.tau / 4 + 0.3
    start = (5.0 * math.cos(bearing), 5.0 * math.sin(bearing))
    goal = (-start[0], -start[1], bearing + math.pi)
    route = route_graph((segment,), CLEARANCE).route(start, goal, APPROACH)
    assert route and _turned(route, start) > 0.0
    assert min(segment.distance(*p) for p in route) >= segment.radius + CLEARANCE - 1e-6


@pytest.mark.parametrize("k", range(4))
def test_routes_round_a_lone_post_keep_the_clearance_from_its_zone(k: int) -> None:
    """Robots crossing a ring round a post go round its Eq. (27) zone (every via-point
    the clearance beyond the influence radius), still counter-clockwise; round the body
    alone the via-points lie inside the zone, where -K_avoid/x_OA holds a robot short."""
    centre = Obstacle(x=0.0, y=0.0, radius=1.2, body=0.6)
    bearing = k * math.tau / 4 + 0.01
    start = (5.0 * math.cos(bearing), 5.0 * math.sin(bearing))
    goal = (-start[0], -start[1], bearing + math.pi)
    route = route_graph((centre,), CLEARANCE).route(start, goal, APPROACH)
    assert route and _turned(route, start) > 0.0
    assert min(math.hypot(*p) for p in route) >= centre.radius + CLEARANCE
    body_only = Roadmap.build([centre], CLEARANCE).route(start, goal, APPROACH)
    assert body_only and min(math.hypot(*p) for p in body_only) < centre.radius


def test_a_goal_inside_a_lone_post_s_zone_is_still_reached_round_its_body() -> None:
    centre = Obstacle(x=0.0, y=0.0, radius=2.0, body=0.3)
    graph = route_graph((centre,), CLEARANCE)
    route = graph.route((-4.0, 0.0), (1.0, 0.0, 0.0), APPROACH)
    assert route is not None
    assert route == Roadmap.build([centre], CLEARANCE).route((-4.0, 0.0), (1.0, 0.0, 0.0), APPROACH)


def zoned_post(x: float, y: float, body: float, zone: float) -> Obstacle:
    return Obstacle(x=x, y=y, body=body, radius=body + zone)


zoned_posts = st.lists(
    st.builds(zoned_post, coord, coord, st.floats(0.05, 0.6), st.floats(0.0, 1.0)),
    min_size=1,
    max_size=4,
)


@settings(max_examples=300, deadline=None)
@given(
    zoned_posts,
    st.lists(
        st.builds(wall, st.tuples(coord, coord), st.tuples(coord, coord), st.floats(0.05, 0.2)),
        max_size=2,
    ),
    st.tuples(st.floats(-6.0, -1.0), st.floats(-6.0, 6.0)),
    st.tuples(st.floats(1.0, 6.0), st.floats(-6.0, 6.0), st.floats(-math.pi, math.pi)),
)
def test_the_fleet_s_routes_keep_the_clearance_and_reach_what_the_bodies_leave_open(
    post_list: list[Obstacle],
    wall_list: list[Obstacle],
    start: Pt,
    goal: tuple[float, float, float],
) -> None:
    """Routes round lone posts' zones (:func:`route_graph`) keep the clearance from every
    body, and a goal is reachable exactly when it is round the bodies alone; a route that
    differs from the way round the bodies keeps the clearance from every grown post."""
    obstacles = post_list + wall_list
    for point in (start, goal[:2]):
        assume(all(o.distance(*point) > o.body_radius + 0.02 for o in obstacles))
    route = route_graph(tuple(obstacles), CLEARANCE).route(start, goal, APPROACH)
    plain = Roadmap.build(obstacles, CLEARANCE).route(start, goal, APPROACH)
    assert (route is None) == (plain is None)
    event("none" if route is None else "round the bodies" if route == plain else "round zones")
    if route is None:
        return
    assert_keeps_clearance(obstacles, CLEARANCE, start, goal, APPROACH, route)
    if route != plain:
        grown = list(roundabouts(tuple(obstacles), CLEARANCE))
        assert_keeps_clearance(grown, CLEARANCE, start, goal, APPROACH, route)
