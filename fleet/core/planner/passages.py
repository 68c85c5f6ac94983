"""Narrow passages found in the walls: single-robot zones nobody had to declare (pure).

A corridor between two walls where two robots cannot pass each other is a trap for robots
meeting in it from both ends: each one's safety filter stops it nose to nose with the
other, and neither can get by. :func:`narrow_passages` finds such passages in a site's
obstacles (shapely geometry) so the fleet can hold each one as a single-robot zone
(:mod:`fleet.core.zones`).

World frame, metres. With robots of radius R keeping ``clearance_m`` (c) from every body
(the route graph's clearance, :mod:`fleet.core.planner.roadmap`), the *free* region is where
a robot's centre may be: everything farther than c from every obstacle's body. Two robots
pass each other side by side when their centres can be ``pass_m`` apart across the free
region -- by default c + R, each keeping the clearance from the other's body as from a
wall. So the free region's *opening* by a disc of diameter ``pass_m`` (shapely's buffer
in, then out) is where robots can pass; the rest of the free region is narrow. A narrow
piece that joins the wide region in two places or more (it leads somewhere: a corridor, a
gate) is a passage; a narrow pocket with one mouth (a dead end, a bay between posts, a
room's corner) is not. Each passage, grown by R so that a robot holds it before its body
is in, is one zone, named ``passage-1``, ``passage-2``, ... from west to east (then south
to north), where robots going the same way may follow each other (``convoys``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import shapely

from fleet.core.planner.roadmap import obstacle_geometries
from fleet.core.wire import Obstacle
from fleet.core.zones import ZoneShape

#: [m] the outline's simplification tolerance (a zone is an order, not a fence).
_SIMPLIFY_M = 0.02
#: [m] how far beyond the obstacles the free region is taken (the outside is wide).
_BEYOND_M = 2.0
#: [m] how much a narrow piece and the wide region must overlap, grown, to touch.
_TOUCH_M = 0.01
#: A narrow piece smaller than this share of a disc of diameter ``pass_m`` is a sliver
#: (the rounding of a corner by the opening), not a passage.
_SLIVER = 0.25


def narrow_passages(
    obstacles: Sequence[Obstacle],
    clearance_m: float,
    robot_radius_m: float,
    pass_m: float | None = None,
) -> tuple[ZoneShape, ...]:
    """The narrow passages of ``obstacles`` as single-robot zones (module docstring);
    ``pass_m`` [m]: the centre distance two robots need to pass (default clearance +
    robot radius). Cached per obstacle set and sizes."""
    width = clearance_m + robot_radius_m if pass_m is None else pass_m
    if not (math.isfinite(clearance_m) and clearance_m >= 0 and width > 0):
        raise ValueError(f"clearance {clearance_m} m and pass width {width} m must be >= 0")
    return _passages(tuple(obstacles), float(clearance_m), float(robot_radius_m), float(width))


@functools.lru_cache(maxsize=16)
def _passages(
    obstacles: tuple[Obstacle, ...], clearance: float, radius: float, width: float
) -> tuple[ZoneShape, ...]:
    if not obstacles:
        return ()
    shapes = obstacle_geometries(obstacles)
    bodies = [o.body_radius for o in obstacles]
    forbidden = shapely.union_all(shapely.buffer(shapes, [b + clearance for b in bodies]))
    xmin, ymin, xmax, ymax = forbidden.bounds
    beyond = _BEYOND_M + width
    box = shapely.box(xmin - beyond, ymin - beyond, xmax + beyond, ymax + beyond)
    free = box.difference(forbidden)
    wide = free.buffer(-width / 2).buffer(width / 2)
    narrow = free.difference(wide)
    sliver = _SLIVER * math.pi * (width / 2) ** 2
    found = []
    for piece in getattr(narrow, "geoms", [narrow]):
        if piece.is_empty or piece.area < sliver:
            continue
        mouths = piece.buffer(_TOUCH_M).intersection(wide)
        if len(getattr(mouths, "geoms", [mouths])) < 2 or mouths.is_empty:
            continue
        zone = piece.buffer(radius).simplify(_SIMPLIFY_M)
        for part in getattr(zone, "geoms", [zone]):
            outline = tuple((float(x), float(y)) for x, y in part.exterior.coords[:-1])
            if len(outline) >= 3:
                found.append(outline)
    found.sort(key=lambda o: (min(p[0] for p in o), min(p[1] for p in o)))
    return tuple(
        ZoneShape(f"passage-{k + 1}", outline, found=True, convoys=True)
        for k, outline in enumerate(found)
    )


__all__ = ["narrow_passages"]
