"""Plane geometry of the site (pure): distance to a segment (one point, or many points
to many segments at once), whether segments cross, and whether a point lies in a polygon.

World frame, metres. The compiled control step has its own copy of the segment distance
inside the step (:func:`fleet.core.step.obstacle_offset`, the same arithmetic); this module
is for everything outside the control loop: goals, site files, the API's input.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fleet.core.types import FloatArray

Point = tuple[float, float]


def segment_distance(x: float, y: float, a: Point, b: Point) -> float:
    """Distance [m] from (x, y) to the segment from ``a`` to ``b`` (a point when a == b)."""
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length_sq = dx * dx + dy * dy
    t = 0.0
    if length_sq > 0.0:
        t = min(max(((x - ax) * dx + (y - ay) * dy) / length_sq, 0.0), 1.0)
    return math.hypot(ax + t * dx - x, ay + t * dy - y)


def inside_polygon(vertices: Sequence[Point], x: float, y: float) -> bool:
    """Whether (x, y) lies inside the polygon ``vertices`` (even-odd rule; a point on an
    edge may fall either way: callers also use a distance)."""
    inside = False
    j = len(vertices) - 1
    for i, (xi, yi) in enumerate(vertices):
        xj, yj = vertices[j]
        if (yi > y) != (yj > y) and x < (xj - xi) * (y - yi) / (yj - yi) + xi:
            inside = not inside
        j = i
    return inside


def segments_distance(a: Point, b: Point, c: Point, d: Point) -> float:
    """Distance [m] between the segments [a, b] and [c, d] (0 where they cross or touch)."""
    if segments_cross(a, b, c, d):
        return 0.0
    return min(
        segment_distance(*a, c, d),
        segment_distance(*b, c, d),
        segment_distance(*c, a, b),
        segment_distance(*d, a, b),
    )


def _orientation(p: Point, q: Point, r: Point) -> float:
    """Twice the signed area of (p, q, r): > 0 counter-clockwise, 0 collinear."""
    return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])


def segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool:
    """Whether the closed segments [a, b] and [c, d] share a point (touching counts)."""
    o1, o2 = _orientation(a, b, c), _orientation(a, b, d)
    o3, o4 = _orientation(c, d, a), _orientation(c, d, b)
    if ((o1 > 0) != (o2 > 0) and o1 != 0 and o2 != 0) and (
        (o3 > 0) != (o4 > 0) and o3 != 0 and o4 != 0
    ):
        return True

    def on(p: Point, q: Point, r: Point) -> bool:  # r on [p, q], given collinear
        return min(p[0], q[0]) <= r[0] <= max(p[0], q[0]) and min(p[1], q[1]) <= r[1] <= max(
            p[1], q[1]
        )

    return (
        (o1 == 0 and on(a, b, c))
        or (o2 == 0 and on(a, b, d))
        or (o3 == 0 and on(c, d, a))
        or (o4 == 0 and on(c, d, b))
    )


def first_self_crossing(points: Sequence[Point], closed: bool) -> tuple[int, int] | None:
    """The first pair of edges (i, j) of the polyline (closed: polygon) that cross, where
    edge i runs from ``points[i]`` to the next point; neighbouring edges may share their
    common vertex. None: the chain is simple."""
    n = len(points)
    edges = n if closed else n - 1
    for i in range(edges):
        a, b = points[i], points[(i + 1) % n]
        for j in range(i + 1, edges):
            c, d = points[j], points[(j + 1) % n]
            adjacent = j == i + 1 or (closed and i == 0 and j == edges - 1)
            if adjacent:
                # Neighbours share a vertex; they cross only if they fold back on each other.
                shared, other_i, other_j = (b, a, d) if j == i + 1 else (a, b, c)
                if (
                    _orientation(other_i, shared, other_j) == 0
                    and (other_j[0] - shared[0]) * (other_i[0] - shared[0])
                    + (other_j[1] - shared[1]) * (other_i[1] - shared[1])
                    > 0
                ):
                    return i, j
                continue
            if segments_cross(a, b, c, d):
                return i, j
    return None


def segment_distances(xy: FloatArray, starts: FloatArray, ends: FloatArray) -> FloatArray:
    """Distances [m] (T, N, K) from points ``xy`` (T, N, 2) to the K segments from
    ``starts`` (K, 2) to ``ends`` (K, 2) (a point where they coincide):
    :func:`segment_distance`, vectorised."""
    edge = ends - starts  # (K, 2)
    length_sq = (edge * edge).sum(axis=1)  # (K,)
    rel = xy[:, :, None, :] - starts[None, None, :, :]  # (T, N, K, 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(length_sq > 0.0, (rel * edge).sum(axis=3) / length_sq, 0.0)
    t = np.clip(t, 0.0, 1.0)
    offset = rel - t[..., None] * edge[None, None, :, :]
    return np.asarray(np.hypot(offset[..., 0], offset[..., 1]))
