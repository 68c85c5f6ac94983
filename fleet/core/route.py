"""Routes: the via-points a robot passes on its way to its goal (pure).

A route is a list of via-points (x, y) [m], world frame, planned around the site's walls and
posts (:mod:`fleet.core.planner.roadmap`), ending in front of the bay; the paper's law
(17)/(20) then parks the robot on the last leg. The robot aims at each via-point in turn,
facing it with the law that turns the shorter way, and passes it when its centre comes
within the pass-through radius, without stopping (:func:`fleet.core.step.aim`). Robot and
planner run the same table (:func:`route_table`) through the same step, so the planner
predicts what the robot does.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from fleet.core.site import Lane
from fleet.core.step import ROUTE_ROWS, VIA_CW, VIA_HEADING, VIA_X, VIA_Y, wrap_to_2pi
from fleet.core.types import FloatArray, Posture


@dataclass(frozen=True)
class LaneShape:
    """A site's lane as routing sees it (:class:`fleet.core.site.Lane`,
    :mod:`fleet.core.planner.lanes`): its points [m] and whether it is one-way."""

    points: tuple[tuple[float, float], ...]
    one_way: bool = False


def lane_shapes(lanes: Iterable[Lane]) -> tuple[LaneShape, ...]:
    """The site's lanes as :class:`LaneShape` (hashable: route graphs are cached by them)."""
    return tuple(
        LaneShape(tuple((float(x), float(y)) for x, y in lane.points), lane.one_way)
        for lane in lanes
    )


def route_table(
    via: Sequence[tuple[float, float]] | npt.ArrayLike, goal: Posture, cw: bool
) -> FloatArray:
    """The route table of :mod:`fleet.core.step` (``ROUTE_ROWS``, m + 1): the via-points
    ``via`` (m, 2) [m], then the goal with its heading wrapped by (11.a) and the robot's law."""
    points = np.asarray(via, dtype=np.float64).reshape(-1, 2)
    table = np.zeros((ROUTE_ROWS, points.shape[0] + 1))
    table[VIA_X, :-1], table[VIA_Y, :-1] = points[:, 0], points[:, 1]
    table[VIA_X, -1], table[VIA_Y, -1] = goal[0], goal[1]
    table[VIA_HEADING, -1] = wrap_to_2pi(goal[2])
    table[VIA_CW, -1] = 1.0 if cw else 0.0
    return table


def remaining(
    via: Sequence[tuple[float, float]], x: float, y: float, goal: tuple[float, float] | None = None
) -> FloatArray:
    """The via-points (m', 2) [m] a robot at (x, y) [m] still has to pass on route ``via``:
    from the one whose leg (from the via-point before it; the first: the point itself)
    passes nearest to the robot. With the route's ``goal`` (x, y) [m], none is left when
    the robot is on the last leg: nearer to the goal than the last via-point is, and
    nearer to that leg than to any other (without the goal the last via-point always is
    left). The robot does not report which one it aims at; this is the planner's (and the
    dashboard's) estimate."""
    points = np.asarray(via, dtype=np.float64).reshape(-1, 2)
    if points.shape[0] == 0:
        return points
    ends = points if goal is None else np.vstack([points, [goal]])
    a = np.vstack([ends[:1], ends[:-1]])  # each leg's start
    d = ends - a
    length_sq = (d * d).sum(axis=1)
    t = np.where(
        length_sq > 0, ((np.array([x, y]) - a) * d).sum(axis=1) / np.maximum(length_sq, 1e-300), 0.0
    )
    closest = a + np.clip(t, 0.0, 1.0)[:, None] * d
    distance = np.hypot(closest[:, 0] - x, closest[:, 1] - y)
    nearest = int(np.argmin(distance[: points.shape[0]]))
    if goal is not None:
        last_to_goal = math.hypot(goal[0] - points[-1, 0], goal[1] - points[-1, 1])
        if (
            math.hypot(goal[0] - x, goal[1] - y) < last_to_goal
            and distance[-1] <= distance[nearest]
        ):
            return points[:0].copy()  # on the last leg
    return points[nearest:].copy()
