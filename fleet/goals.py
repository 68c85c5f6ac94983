"""Goal validation (the paper's Section 6: a goal must lie outside every influence zone).

Pure. A goal is rejected with :class:`fleet.tasks.GoalRejected`, whose message names what
it conflicts with, when it lies

* outside the yard rectangle ``(xmin, xmax, ymin, ymax)`` [m];
* inside (or on the edge of) a static obstacle's influence zone -- there the repulsion of
  Eq. (27) would fight the posture law for ever;
* within the peer influence radius [m] of another active task's goal or of a parked robot
  (two robots parked that close would push each other through Eq. (27)).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from fleet.tasks import GoalRejected
from fleet.wire import Obstacle, Pose

Yard = tuple[float, float, float, float]


@dataclass(frozen=True)
class Occupied:
    """A point another robot will stand on: an active goal or a parked robot [m]."""

    x: float
    y: float
    what: str  # e.g. "the goal of task 1a2b" or "parked robot r3"


def validate_goal(
    goal: Pose,
    yard: Yard,
    obstacles: Iterable[Obstacle],
    occupied: Iterable[Occupied],
    peer_radius: float,
) -> None:
    """Raise :class:`GoalRejected` if ``goal`` is not a valid parking posture."""
    xmin, xmax, ymin, ymax = yard
    if not (math.isfinite(goal.x) and math.isfinite(goal.y) and math.isfinite(goal.theta)):
        raise GoalRejected("goal must be finite")
    if not (xmin <= goal.x <= xmax and ymin <= goal.y <= ymax):
        raise GoalRejected(
            f"goal ({goal.x:.2f}, {goal.y:.2f}) is outside the yard "
            f"x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}] m"
        )
    for i, obs in enumerate(obstacles):
        d = math.hypot(goal.x - obs.x, goal.y - obs.y)
        if d <= obs.radius:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) lies inside the influence zone of obstacle "
                f"{i} at ({obs.x:.2f}, {obs.y:.2f}) (radius {obs.radius:g} m, distance {d:.2f} m)"
            )
    for other in occupied:
        d = math.hypot(goal.x - other.x, goal.y - other.y)
        if d <= peer_radius:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) is {d:.2f} m from {other.what} at "
                f"({other.x:.2f}, {other.y:.2f}); goals must be more than the peer influence "
                f"radius {peer_radius:g} m apart"
            )
