"""Goal validation (the paper's Section 6: a goal must lie outside every influence zone).

Pure. A goal is rejected with :class:`fleet.core.tasks.GoalRejected`, whose message names what
it conflicts with, when it lies

* outside the yard rectangle ``(xmin, xmax, ymin, ymax)`` [m];
* inside (or on the edge of) a static obstacle's influence zone -- there the repulsion of
  Eq. (27) would fight the posture law for ever -- or so near its body that the parked
  robot's body (``margin``, its radius [m]) would come within ``contact_margin`` [m] of it
  (the safety filter would never let it arrive);
* inside a keep-out zone of the site map (:mod:`fleet.core.site`), or so near one that the
  parked robot's body (``margin``, its radius [m]) would reach into it;
* inside a single-robot zone (:mod:`fleet.core.zones`), or so near one that the parked
  robot's body would reach into it: a robot parked there would hold the zone for ever;
* within the peer influence radius [m] of another active task's goal or of a parked robot
  (two robots parked that close would push each other through Eq. (27)).

:class:`GoalIndex` keeps the active goals in a uniform grid (cells of the peer radius)
updated as tasks come and go, so the spacing check of a new goal looks at the few goals in
the neighbouring cells instead of every active task.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from fleet.core.site import KeepOutZone
from fleet.core.tasks import GoalRejected
from fleet.core.wire import Obstacle, Pose
from fleet.core.zones import ZoneShape

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
    keep_out: Iterable[KeepOutZone] = (),
    margin: float = 0.0,
    contact_margin: float = 0.0,
    zones: Iterable[ZoneShape] = (),
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
        d = obs.distance(goal.x, goal.y)
        what = f"obstacle {i} at ({obs.x:.2f}, {obs.y:.2f})"
        if obs.end is not None:
            ex, ey = obs.far_end
            what = f"wall segment {i} from ({obs.x:.2f}, {obs.y:.2f}) to ({ex:.2f}, {ey:.2f})"
        if d <= obs.radius:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) lies inside the influence zone of {what} "
                f"(radius {obs.radius:g} m, distance {d:.2f} m)"
            )
        reach = obs.body_radius + margin + contact_margin
        if d <= reach:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) is {d:.2f} m from {what}: a parked robot "
                f"(radius {margin:g} m) would come within {contact_margin:g} m of its body "
                f"(radius {obs.body_radius:g} m)"
            )
    for zone in keep_out:
        d = zone.distance(goal.x, goal.y)
        if d == 0.0:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) lies inside keep-out zone {zone.name}"
            )
        if d <= margin:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) is {d:.2f} m from keep-out zone {zone.name}: "
                f"a parked robot (radius {margin:g} m) would reach into it"
            )
    for single in zones:
        d = single.distance(goal.x, goal.y)
        if d <= margin:
            where = "lies inside" if d == 0.0 else f"is {d:.2f} m from"
            kind = "narrow passage" if single.found else "single-robot zone"
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) {where} the {kind} {single.name}: a robot "
                "parked there would hold it, and no other robot could drive through"
            )
    for other in occupied:
        d = math.hypot(goal.x - other.x, goal.y - other.y)
        if d <= peer_radius:
            raise GoalRejected(
                f"goal ({goal.x:.2f}, {goal.y:.2f}) is {d:.2f} m from {other.what} at "
                f"({other.x:.2f}, {other.y:.2f}); goals must be more than the peer influence "
                f"radius {peer_radius:g} m apart"
            )


class GoalIndex:
    """Points by key in a uniform grid of ``cell`` [m]; ``near`` finds those within a radius.

    ``add``/``remove`` cost O(1); ``near(x, y, r)`` looks at the cells overlapping the
    square of half-side ``r`` around (x, y), so it costs O(points in those cells) -- with
    ``cell`` of the order of ``r`` and points kept more than ``r`` apart, a handful.
    """

    def __init__(self, cell: float) -> None:
        if not (cell > 0 and math.isfinite(cell)):
            raise ValueError("cell must be a positive finite length")
        self.cell = float(cell)
        self._points: dict[str, Occupied] = {}
        self._cells: dict[tuple[int, int], dict[str, Occupied]] = {}

    def _cell_of(self, x: float, y: float) -> tuple[int, int]:
        return (math.floor(x / self.cell), math.floor(y / self.cell))

    def __len__(self) -> int:
        return len(self._points)

    def __contains__(self, key: object) -> bool:
        return key in self._points

    def add(self, key: str, point: Occupied) -> None:
        """Insert (or move) ``key`` at ``point``; coordinates must be finite."""
        if not (math.isfinite(point.x) and math.isfinite(point.y)):
            raise ValueError("point must be finite")
        self.remove(key)
        self._points[key] = point
        self._cells.setdefault(self._cell_of(point.x, point.y), {})[key] = point

    def remove(self, key: str) -> None:
        """Drop ``key`` (nothing if absent)."""
        point = self._points.pop(key, None)
        if point is None:
            return
        c = self._cell_of(point.x, point.y)
        bucket = self._cells[c]
        del bucket[key]
        if not bucket:
            del self._cells[c]

    def near(self, x: float, y: float, radius: float) -> Iterator[Occupied]:
        """Points at a distance <= ``radius`` [m] from (x, y), nearest first."""
        if not (math.isfinite(x) and math.isfinite(y)) or radius < 0:
            return iter(())
        # A point just outside the square can still round to a distance of exactly
        # ``radius`` (hypot rounds): look a hair further so the grid never misses it.
        reach = radius * (1.0 + 1e-9) + 1e-12
        i0, j0 = self._cell_of(x - reach, y - reach)
        i1, j1 = self._cell_of(x + reach, y + reach)
        found: list[tuple[float, Occupied]] = []
        if (i1 - i0 + 1) * (j1 - j0 + 1) > len(self._cells):  # huge radius: scan the cells
            buckets: Iterable[dict[str, Occupied]] = self._cells.values()
        else:
            buckets = (
                b
                for i in range(i0, i1 + 1)
                for j in range(j0, j1 + 1)
                if (b := self._cells.get((i, j))) is not None
            )
        for bucket in buckets:
            for p in bucket.values():
                d = math.hypot(x - p.x, y - p.y)
                if d <= radius:
                    found.append((d, p))
        found.sort(key=lambda dp: dp[0])
        return iter([p for _, p in found])
