"""Single-robot zones' geometry: which ways enter a zone, where a robot is in one; shapely
is the independent oracle."""

from __future__ import annotations

import math

import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.site import Circle, Site, Yard, Zone
from fleet.core.zones import ZoneShape, declared, entered, way

coordinate = st.floats(-5.0, 5.0, allow_nan=False)
points = st.tuples(coordinate, coordinate)


@st.composite
def star_polygons(draw: st.DrawFn) -> tuple[tuple[float, float], ...]:
    """A simple polygon: vertices at increasing angles round a centre (star-shaped)."""
    n = draw(st.integers(3, 9))
    cx, cy = draw(points)
    angles = sorted(draw(st.lists(st.floats(0, 2 * math.pi), min_size=n, max_size=n, unique=True)))
    radii = draw(st.lists(st.floats(0.3, 3.0), min_size=n, max_size=n))
    outline = tuple(
        (cx + r * math.cos(a), cy + r * math.sin(a)) for a, r in zip(angles, radii, strict=True)
    )
    polygon = shapely.Polygon(outline)
    if not polygon.is_valid or polygon.area < 0.05:
        outline = ((cx, cy), (cx + 1.0, cy), (cx + 1.0, cy + 1.0), (cx, cy + 1.0))
    return outline


@settings(max_examples=300, deadline=None)
@given(star_polygons(), st.lists(points, min_size=1, max_size=6))
def test_a_way_enters_a_zone_exactly_when_shapely_says_they_meet(
    outline: tuple[tuple[float, float], ...], path: list[tuple[float, float]]
) -> None:
    zone = ZoneShape("z", outline)
    # shapely's line_locate_point divides by a leg's length: legs of ~0 m (1e-202) left out
    kept = [p for k, p in enumerate(path) if k == 0 or math.dist(p, path[k - 1]) > 1e-9]
    line = shapely.Point(path[0]) if len(kept) == 1 else shapely.LineString(kept)
    polygon = shapely.Polygon(outline)
    near_edge = polygon.exterior.distance(line) < 1e-9
    if not near_edge:  # touching an edge may go either way (rounding)
        assert zone.entered_by(path) == polygon.intersects(line)
    along = zone.distance_along(path)
    assert (along < math.inf) == zone.entered_by(path)
    if along < math.inf and not near_edge and line.length > 1e-9:
        meet = line.intersection(polygon)
        first = min(line.project(shapely.Point(c)) for c in shapely.get_coordinates(meet))
        assert math.isclose(along, first, abs_tol=1e-6)


@settings(max_examples=300, deadline=None)
@given(star_polygons(), points)
def test_a_point_is_in_a_zone_as_shapely_says_and_its_distance_is_shapelys(
    outline: tuple[tuple[float, float], ...], p: tuple[float, float]
) -> None:
    zone = ZoneShape("z", outline)
    polygon = shapely.Polygon(outline)
    point = shapely.Point(p)
    if polygon.exterior.distance(point) > 1e-9:
        assert zone.contains(*p) == polygon.contains(point)
    assert math.isclose(zone.distance(*p), polygon.distance(point), abs_tol=1e-9)


def test_the_distance_along_a_way_is_how_far_the_robot_drives_before_it_enters() -> None:
    gate = ZoneShape("gate", ((0.0, -1.0), (1.0, -1.0), (1.0, 1.0), (0.0, 1.0)))
    assert gate.distance_along([(-5.0, 0.0), (-2.0, 0.0), (3.0, 0.0)]) == 5.0
    assert gate.distance_along([(0.5, 0.0), (3.0, 0.0)]) == 0.0  # starts inside
    assert gate.distance_along([(-5.0, 5.0), (5.0, 5.0)]) == math.inf


def test_the_site_maps_zones_are_shapes_and_a_circle_lies_inside_its_polygon() -> None:
    site = Site(
        yard=Yard(xmin=-10, xmax=10, ymin=-10, ymax=10),
        zones=[
            Zone(name="gate", rect={"xmin": -1, "xmax": 1, "ymin": -2, "ymax": 2}),
            Zone(name="turn", circle=Circle(x=5.0, y=5.0, radius=1.0)),
        ],
    )
    gate, turn = declared(site)
    assert (gate.name, gate.found, len(gate.outline)) == ("gate", False, 4)
    for k in range(36):  # the circle's rim is inside the polygon round it
        a = 2 * math.pi * k / 36
        assert turn.contains(5.0 + 0.999 * math.cos(a), 5.0 + 0.999 * math.sin(a))
    assert entered((gate, turn), [(-5.0, 0.0), (5.0, 0.0), (5.0, 8.0)]) == ("gate", "turn")
    assert declared(None) == ()


def test_a_way_is_the_rest_of_the_route_from_where_the_robot_is() -> None:
    via = [(0.0, 0.0), (5.0, 0.0), (5.0, 5.0)]
    assert way(4.0, 0.1, via, (8.0, 5.0), rest=False)[1:] == [*via, (8.0, 5.0)]
    rest = way(4.0, 0.1, via, (8.0, 5.0))  # past the first via-point, on the second leg
    assert rest[0] == (4.0, 0.1) and rest[-1] == (8.0, 5.0)
    assert (0.0, 0.0) not in rest and (5.0, 5.0) in rest
