"""Routes: the via-points a robot passes on its way to its goal (pure).

A route is a list of via-points (x, y) [m], world frame, planned around the site's walls and
posts (:mod:`fleet.core.planner.roadmap`), ending in front of the bay; the paper's law
(17)/(20) then parks the robot on the last leg. The robot aims at each via-point in turn
with a posture: the heading of the leg that leaves it, and the law whose rotation sense
makes the turn there (:func:`via_postures`, the fleet's side). It passes the via-point when
its centre comes within the pass-through radius, without stopping
(:func:`fleet.core.step.next_leg`). Robot and planner run the same table
(:func:`route_table`), so the planner predicts what the robot does.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fleet.core.step import ROUTE_ROWS, VIA_HEADING, wrap_headings
from fleet.core.types import FloatArray, Posture
from fleet.core.wire import Waypoint

#: Most via-points of one route (a route is a handful of aisle corners).
MAX_VIA_POINTS = 64


def via_postures(start: Posture, points: Sequence[tuple[float, float]]) -> FloatArray:
    """(m, 4) rows (x [m], y [m], heading [rad], cw) for via-points ``points`` of a robot
    leaving posture ``start``: the heading of the leg that arrives at the point (the robot
    drives each leg straight once it faces along it), and the law whose rotation sense makes
    the turn onto that leg from the one before (from ``start``'s heading for the first):
    cw 1.0 (law (20)) for a right turn, else 0.0 (law (17))."""
    rows = np.zeros((len(points), ROUTE_ROWS))
    x0, y0, facing = start
    for k, (x, y) in enumerate(points):
        heading = math.atan2(y - y0, x - x0)
        turn = math.remainder(heading - facing, 2.0 * math.pi)
        rows[k] = (x, y, heading, 1.0 if turn < 0.0 else 0.0)
        x0, y0, facing = x, y, heading
    return rows


def route_table(via: FloatArray, goal: Posture, cw: bool) -> FloatArray:
    """The route table of :mod:`fleet.core.step` (``ROUTE_ROWS``, m + 1): the via-point
    rows ``via`` (m, 4) then the goal with the robot's law, headings wrapped by (11.a)."""
    rows = np.asarray(via, dtype=np.float64).reshape(-1, ROUTE_ROWS)
    entries = np.vstack([rows, [[goal[0], goal[1], goal[2], 1.0 if cw else 0.0]]])
    entries[:, VIA_HEADING] = wrap_headings(np.ascontiguousarray(entries[:, VIA_HEADING]))
    return np.ascontiguousarray(entries.T)


def waypoints(via: FloatArray) -> tuple[Waypoint, ...]:
    """Via-point rows (m, 4) of :func:`via_postures` as the wire's waypoints."""
    return tuple(
        Waypoint(x=float(x), y=float(y), theta=float(h), law="cw" if cw else "ccw")
        for x, y, h, cw in np.asarray(via).reshape(-1, ROUTE_ROWS)
    )


def via_rows(route: Sequence[Waypoint]) -> FloatArray:
    """The wire's waypoints as via-point rows (m, 4) (x, y, heading, cw)."""
    rows = [(w.x, w.y, w.theta, 1.0 if w.law == "cw" else 0.0) for w in route]
    return np.array(rows, dtype=np.float64).reshape(-1, ROUTE_ROWS)
