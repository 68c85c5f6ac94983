"""Narrow passages found in the walls: a corridor two robots cannot pass in is a zone; a
wide one, a dead end and a room's corners are not."""

from __future__ import annotations

import pytest

from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.passages import narrow_passages
from fleet.core.site import Wall
from fleet.core.wire import Obstacle

RADIUS = 0.2
CLEARANCE = PlannerConfig().route_clearance(RADIUS, 0.05)  # 0.4 m


def dumbbell(half_width: float, length: float = 4.0) -> list[Obstacle]:
    """Two 6 x 10 m rooms joined by a corridor ``2 half_width`` wide (wall centre lines)
    and ``2 length`` long."""
    h, a = half_width, length
    points = [(-a - 6, 5), (-a, 5), (-a, h), (a, h), (a, 5), (a + 6, 5), (a + 6, -5),
              (a, -5), (a, -h), (-a, -h), (-a, -5), (-a - 6, -5)]  # fmt: skip
    return Wall(points=points, closed=True, body=0.05).segments()


def test_a_corridor_too_narrow_to_pass_in_is_one_zone_from_mouth_to_mouth() -> None:
    (zone,) = narrow_passages(dumbbell(0.6), CLEARANCE, RADIUS)
    assert zone.name == "passage-1" and zone.found
    assert all(zone.contains(x, 0.0) for x in (-3.9, -2.0, 0.0, 2.0, 3.9))  # the corridor
    assert not zone.contains(-6.0, 0.0) and not zone.contains(6.0, 0.0)  # the rooms
    assert not zone.contains(0.0, 1.0)  # beyond the walls
    assert zone.entered_by([(-8.0, 2.0), (-4.5, 0.0), (4.5, 0.0), (8.0, -2.0)])
    assert not zone.entered_by([(-8.0, 3.0), (-6.0, -3.0)])  # a way inside the west room


def test_a_corridor_wide_enough_to_pass_in_is_no_zone() -> None:
    assert narrow_passages(dumbbell(1.2), CLEARANCE, RADIUS) == ()


def test_the_pass_width_decides_what_is_narrow() -> None:
    corridor = dumbbell(1.2)  # 2.3 m between the bodies: 1.5 m for a centre
    assert narrow_passages(corridor, CLEARANCE, RADIUS, pass_m=1.6) != ()
    assert narrow_passages(corridor, CLEARANCE, RADIUS, pass_m=1.4) == ()


def test_a_dead_end_and_a_rooms_corners_are_no_passage() -> None:
    box = Wall(points=[(-5, -5), (5, -5), (5, 5), (-5, 5)], closed=True, body=0.05).segments()
    pocket = Wall(points=[(5, 0.5), (7, 0.5), (7, -0.5), (5, -0.5)], body=0.05).segments()
    # a room with a narrow pocket (one mouth) cut into its east wall
    room = [
        *Wall(
            points=[(5, 0.5), (5, 5), (-5, 5), (-5, -5), (5, -5), (5, -0.5)], body=0.05
        ).segments(),
        *pocket,
    ]
    assert narrow_passages(box, CLEARANCE, RADIUS) == ()
    assert narrow_passages(room, CLEARANCE, RADIUS) == ()


def test_a_narrow_gap_between_two_posts_is_a_passage_and_a_wide_one_is_not() -> None:
    def posts(gap: float) -> list[Obstacle]:
        half = gap / 2 + 0.2
        return [Obstacle(x=x, y=0.0, radius=0.5, body=0.2) for x in (-half, half)]

    (zone,) = narrow_passages(posts(1.0), CLEARANCE, RADIUS)
    assert zone.contains(0.0, 0.0) and not zone.contains(0.0, 2.0)
    assert narrow_passages(posts(2.5), CLEARANCE, RADIUS) == ()
    assert narrow_passages([], CLEARANCE, RADIUS) == ()


def test_bad_sizes_are_refused() -> None:
    with pytest.raises(ValueError, match="clearance"):
        narrow_passages(dumbbell(0.6), float("nan"), RADIUS)
