"""The site map: keep-out zone geometry, bays, consistency checks; goals in keep-out zones."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from fleet.core.goals import validate_goal
from fleet.core.site import Bay, KeepOutZone, Rect, Site, Wall, Yard, Zone
from fleet.core.tasks import GoalRejected
from fleet.core.wire import Obstacle, Pose

YARD = Yard(xmin=-10, xmax=10, ymin=-10, ymax=10)
SQUARE = KeepOutZone(name="sq", rect=Rect(xmin=0, xmax=2, ymin=0, ymax=2))
SQUARE_POLY = KeepOutZone(name="sqp", polygon=[(0, 0), (2, 0), (2, 2), (0, 2)])

coords = st.floats(-5, 5, allow_nan=False)


@given(coords, coords)
def test_a_rectangle_and_the_same_polygon_measure_the_same_distance(x: float, y: float) -> None:
    dx = max(0.0 - x, 0.0, x - 2.0)
    dy = max(0.0 - y, 0.0, y - 2.0)
    expected = math.hypot(dx, dy)
    assert SQUARE.distance(x, y) == pytest.approx(expected, abs=1e-9)
    assert SQUARE_POLY.distance(x, y) == pytest.approx(expected, abs=1e-9)


@given(coords, coords)
def test_circle_distance_is_the_gap_to_the_rim(x: float, y: float) -> None:
    zone = KeepOutZone.model_validate({"name": "c", "circle": {"x": 1, "y": -1, "radius": 0.5}})
    assert zone.distance(x, y) == pytest.approx(max(0.0, math.hypot(x - 1, y + 1) - 0.5))


def test_concave_polygon_inside_and_outside() -> None:
    ell = KeepOutZone(name="L", polygon=[(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)])
    assert ell.distance(0.5, 2.5) == 0.0 and ell.distance(2.5, 0.5) == 0.0
    assert ell.distance(2.0, 2.0) == pytest.approx(1.0)  # in the notch: 1 m from both arms


@pytest.mark.parametrize(
    "zone",
    [
        {"name": "none"},
        {"name": "two", "circle": {"x": 0, "y": 0, "radius": 1}, "rect": [0, 1, 0, 1]},
        {"name": "flat", "polygon": [[0, 0], [1, 1], [2, 2]]},
        {"name": "bad name!", "circle": {"x": 0, "y": 0, "radius": 1}},
        {"name": "r", "rect": {"xmin": 1, "xmax": 0, "ymin": 0, "ymax": 1}},
        {"name": "bowtie", "polygon": [[0, 0], [2, 2], [2, 0], [0, 2]]},
    ],
)
@pytest.mark.parametrize("kind", [KeepOutZone, Zone])
def test_invalid_zones_are_rejected(zone: dict[str, object], kind: type[KeepOutZone]) -> None:
    with pytest.raises(ValidationError):
        kind.model_validate(zone)


def test_a_self_crossing_polygon_is_refused_naming_its_edges() -> None:
    with pytest.raises(ValidationError, match=r"polygon: edges 0 and 2 cross"):
        Zone.model_validate({"name": "bowtie", "polygon": [[0, 0], [2, 2], [2, 0], [0, 2]]})


def test_a_bay_in_or_near_a_single_robot_zone_is_a_problem_and_zone_names_are_unique() -> None:
    gate = Zone(name="gate", rect=Rect(xmin=-1, xmax=1, ymin=-1, ymax=1))
    site = Site(
        yard=YARD,
        zones=[gate],
        bays=[
            Bay(name="in", pose=Pose(x=0.0, y=0.0)),
            Bay(name="edge", pose=Pose(x=0.0, y=-1.1)),
            Bay(name="fine", pose=Pose(x=5.0, y=5.0)),
        ],
    )
    problems = [str(p) for p in site.problems(robot_radius=0.2, peer_radius=1.0)]
    assert any(p.startswith("bay in is within 0.2 m of single-robot zone gate") for p in problems)
    assert any(p.startswith("bay edge is within 0.2 m of single-robot zone gate") for p in problems)
    assert not any("bay fine" in p for p in problems)
    with pytest.raises(ValidationError, match="two single-robot zones are named 'gate'"):
        Site(yard=YARD, zones=[gate, gate])


def bay(name: str, x: float, y: float, group: str | None = None) -> Bay:
    return Bay(name=name, pose=Pose(x=x, y=y), group=group)


def test_site_rejects_duplicate_names_and_bays_outside_the_yard() -> None:
    with pytest.raises(ValidationError, match="two bays are named 'A1'"):
        Site(yard=YARD, bays=[bay("A1", 0, 0), bay("A1", 5, 5)])
    with pytest.raises(ValidationError, match="bay Z at \\(11, 0\\) is outside the yard"):
        Site(yard=YARD, bays=[bay("Z", 11, 0)])
    with pytest.raises(ValidationError, match="xmin < xmax"):
        Yard(xmin=1, xmax=1, ymin=0, ymax=1)


def test_problems_name_bays_too_close_in_obstacles_or_near_zones() -> None:
    site = Site(
        yard=YARD,
        obstacles=[Obstacle(x=-5, y=-5, radius=1.0)],
        keep_out=[SQUARE],
        bays=[bay("ok", 8, 8), bay("near1", 5, 0), bay("near2", 5.5, 0.5), bay("pillar", -5, -4.5),
              bay("edge", 2.1, 1)],
    )  # fmt: skip
    problems = [(p.loc, str(p)) for p in site.problems(robot_radius=0.2, peer_radius=1.0)]
    pillar = "bay pillar lies within 1 m of the obstacle at (-5, -5) (distance 0.50 m; "
    pillar += "influence radius 1 m, body 0.1 m plus a robot's 0.2 m)"
    assert (("bays", 3, "pose"), pillar) in problems
    assert (("bays", 4, "pose"), "bay edge is within 0.2 m of keep-out zone sq") in problems
    assert any(
        loc == ("bays", 2, "pose") and "near1 and near2 are 0.71 m apart" in m
        for loc, m in problems
    )
    assert len(problems) == 3
    assert site.bay("ok") == bay("ok", 8, 8) and site.bay("nope") is None


def test_group_lists_the_bays_of_a_group() -> None:
    site = Site(yard=YARD, bays=[bay("C1", 5, 5, "charging"), bay("A1", 0, 0)])
    assert [b.name for b in site.group("charging")] == ["C1"]
    assert site.group("none") == []


def test_goals_inside_or_too_near_a_keep_out_zone_are_rejected_with_the_reason() -> None:
    def check(x: float, y: float) -> None:
        validate_goal(Pose(x=x, y=y), YARD.as_tuple(), [], [], 1.0, [SQUARE], margin=0.2)

    with pytest.raises(GoalRejected, match=r"goal \(1.00, 1.00\) lies inside keep-out zone sq"):
        check(1.0, 1.0)
    with pytest.raises(GoalRejected, match=r"0\.10 m from keep-out zone sq: a parked robot"):
        check(2.1, 1.0)
    check(2.3, 1.0)  # clear of the zone by more than the robot's radius


# -- walls -------------------------------------------------------------------------------------
def test_a_wall_is_one_segment_obstacle_per_edge_closed_or_open() -> None:
    square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    closed = Wall(points=square, closed=True, body=0.1)
    assert [(o.x, o.y, o.far_end) for o in closed.segments()] == [
        (0.0, 0.0, (2.0, 0.0)), (2.0, 0.0, (2.0, 2.0)), (2.0, 2.0, (0.0, 2.0)),
        (0.0, 2.0, (0.0, 0.0)),
    ]  # fmt: skip
    assert all(o.body_radius == 0.1 for o in closed.segments())
    assert len(Wall(points=square).segments()) == 3
    site = Site(yard=YARD, obstacles=[Obstacle(x=5, y=5)], walls=[closed])
    assert len(site.static_obstacles()) == 5 and site.static_obstacles()[0].end is None


@given(coords, coords)
def test_the_distance_to_a_wall_segment_is_to_its_closest_point(x: float, y: float) -> None:
    wall = Obstacle(x=0.0, y=0.0, end=(2.0, 0.0), radius=0.3, body=0.1)
    along = min(max(x, 0.0), 2.0)
    assert wall.distance(x, y) == pytest.approx(math.hypot(x - along, y), abs=1e-12)
    assert Obstacle(x=1.0, y=1.0).distance(x, y) == pytest.approx(math.hypot(x - 1, y - 1))


@pytest.mark.parametrize(
    ("wall", "message"),
    [
        ({"points": [(0, 0), (2, 2), (2, 0), (0, 2)], "closed": True}, "crosses itself (edge 0"),
        ({"points": [(0, 0), (2, 0), (1, 0)]}, "crosses itself (edge 0, from point 0, and edge 1"),
        ({"points": [(0, 0), (0, 0), (1, 1)]}, "point 1 repeats point 0"),
        (
            {"points": [(0, 0), (1, 1)], "closed": True},
            "a closed wall (a polygon) needs at least 3",
        ),
        ({"points": [(0, 0), (1, 1)], "body": -0.1}, "greater than or equal to 0"),
        ({"points": [(0, 0), (1, 1)], "body": 0.5, "radius": 0.3}, "exceeds the influence radius"),
        ({"points": [(0, 0), (float("nan"), 1)]}, "finite number"),
        ({"points": [(0, 0)]}, "at least 2 items"),
    ],
)
def test_bad_walls_are_refused_naming_the_problem(wall: dict[str, object], message: str) -> None:
    with pytest.raises(ValidationError, match=re.escape(message)):
        Wall.model_validate(wall)


def test_a_simple_concave_polygon_is_a_valid_wall() -> None:
    ell = [(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)]
    assert len(Wall(points=ell, closed=True).segments()) == 6


def test_goals_on_or_near_a_wall_are_rejected_and_bays_there_are_problems() -> None:
    wall = Wall(points=[(-5.0, 3.0), (5.0, 3.0)], body=0.1)
    segments = wall.segments()
    validate_goal(Pose(x=0.0, y=2.0), YARD.as_tuple(), segments, [], 1.0, margin=0.2)  # 0.9 m clear
    with pytest.raises(GoalRejected, match=r"wall segment 0 from \(-5.00, 3.00\) to \(5.00"):
        validate_goal(Pose(x=4.0, y=3.3), YARD.as_tuple(), segments, [], 1.0, margin=0.2)
    site = Site(yard=YARD, walls=[wall], bays=[bay("far", 0, 0), bay("near", 5.2, 3.2)])
    (problem,) = site.problems(robot_radius=0.2, peer_radius=1.0)
    assert problem.loc == ("bays", 1, "pose") and "the wall from (-5, 3) to (5, 3)" in str(problem)
