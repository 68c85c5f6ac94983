"""Single-robot zones: which zones a robot's way enters, and when it has left them (pure).

A single-robot zone is a gate or a narrow aisle where one robot at a time drives: declared
in the site file (:class:`fleet.core.site.Zone`) or found in the walls as a passage too
narrow for two robots to pass (:mod:`fleet.core.planner.passages`). The fleet holds a zone
for one robot, as it holds a bay for one task -- or, in a zone that allows *convoys* (every
narrow passage found; a declared zone with ``convoys = true``), for robots all going the
same way, one behind the other (never two meeting head on):

* the planner grants a robot every zone its way enters before it starts or goes on
  (:mod:`fleet.core.planner.gates`), each with its pass (:class:`ZonePass`: where the way
  enters and leaves it); a robot whose way enters a zone another robot holds (in a convoy
  zone: one going another way) waits where it stands, with the zone named in its reason;
* the service takes a zone back once its holder stands outside it and the rest of its way
  (:func:`way`) no longer enters it (:class:`fleet.service.zones.ZoneBook`); a robot standing
  in a zone keeps it -- lost, idle or its task ended -- until it leaves or is removed.

A robot is *in* a zone when its centre is inside the zone's outline (the outline should
take in the approaches a robot's body needs). A way is the polyline from the robot's
position through the via-points it has left to its goal, as the robot drives it
(:mod:`fleet.core.route`); it *enters* a zone when one of its points is inside the outline
or one of its legs crosses an edge. Two passes go the same way when the directions from
where they enter to where they leave are less than 60 degrees apart. World frame, metres.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from fleet.core.geometry import inside_polygon, segment_distance, segments_cross
from fleet.core.route import remaining
from fleet.core.site import Site

Point = tuple[float, float]


#: Two passes go the same way when their directions are less than this apart [rad].
SAME_WAY_RAD = math.pi / 3


@dataclass(frozen=True)
class ZonePass:
    """A way through zone ``zone``: where it ``entry`` enters and where it ``exit`` leaves
    it [m] (its start when it starts inside, its end when it ends inside)."""

    zone: str
    entry: Point
    exit: Point

    def same_way(self, other: ZonePass) -> bool:
        """Whether the two passes go the same way (module docstring); a pass that does not
        cross (entry and exit together: a robot standing in the zone) goes no way."""
        ax, ay = self.exit[0] - self.entry[0], self.exit[1] - self.entry[1]
        bx, by = other.exit[0] - other.entry[0], other.exit[1] - other.entry[1]
        norms = math.hypot(ax, ay) * math.hypot(bx, by)
        return norms > 0.0 and ax * bx + ay * by >= math.cos(SAME_WAY_RAD) * norms


@dataclass(frozen=True)
class ZoneShape:
    """A single-robot zone: its ``name``, its ``outline`` (a simple polygon [m], world
    frame), whether it was ``found`` in the walls rather than declared, and whether robots
    going the same way may follow each other through it (``convoys``)."""

    name: str
    outline: tuple[Point, ...]
    found: bool = False
    convoys: bool = False
    _box: tuple[float, float, float, float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.outline) < 3:
            raise ValueError(f"zone {self.name}: an outline needs at least 3 points")
        xs = [p[0] for p in self.outline]
        ys = [p[1] for p in self.outline]
        object.__setattr__(self, "_box", (min(xs), max(xs), min(ys), max(ys)))

    def contains(self, x: float, y: float) -> bool:
        """Whether (x, y) [m] lies inside the outline (even-odd rule; on an edge: either)."""
        xmin, xmax, ymin, ymax = self._box
        return xmin <= x <= xmax and ymin <= y <= ymax and inside_polygon(self.outline, x, y)

    def distance(self, x: float, y: float) -> float:
        """Distance [m] from (x, y) to the zone; 0 inside or on its edge."""
        if self.contains(x, y):
            return 0.0
        points = self.outline
        return min(
            segment_distance(x, y, a, b)
            for a, b in zip(points, points[1:] + points[:1], strict=True)
        )

    def entered_by(self, way: Sequence[Point]) -> bool:
        """Whether the polyline ``way`` [m] enters the zone: a point inside, or a leg that
        crosses (or touches) an edge."""
        if any(self.contains(x, y) for x, y in way):
            return True
        return any(self._crosses(a, b) for a, b in itertools.pairwise(way))

    def _crosses(self, a: Point, b: Point) -> bool:
        """Whether the leg from ``a`` to ``b`` crosses or touches an edge of the outline."""
        xmin, xmax, ymin, ymax = self._box
        if (
            max(a[0], b[0]) < xmin
            or min(a[0], b[0]) > xmax
            or max(a[1], b[1]) < ymin
            or min(a[1], b[1]) > ymax
        ):
            return False
        points = self.outline
        return any(
            segments_cross(a, b, c, d) for c, d in zip(points, points[1:] + points[:1], strict=True)
        )

    def pass_of(self, way: Sequence[Point]) -> ZonePass | None:
        """Where ``way`` enters and leaves the zone (None: it never enters)."""
        if not way:
            return None
        entry: Point | None = way[0] if self.contains(*way[0]) else None
        exit_: Point | None = None
        for a, b in itertools.pairwise(way):
            if not self._crosses(a, b):
                continue
            for t in self._crossings(a, b):
                point = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
                if entry is None:
                    entry = point
                exit_ = point
        if entry is None:
            return None
        if self.contains(*way[-1]) or exit_ is None:
            exit_ = way[-1]
        return ZonePass(self.name, entry, exit_)

    def distance_along(self, way: Sequence[Point]) -> float:
        """How far [m] a robot drives along ``way`` before it enters the zone (0 when it
        starts inside; inf when it never enters)."""
        if not way:
            return math.inf
        if self.contains(*way[0]):
            return 0.0
        travelled = 0.0
        for a, b in itertools.pairwise(way):
            if self._crosses(a, b):
                first = self._crossings(a, b)
                return travelled + (first[0] if first else 0.0) * math.dist(a, b)
            travelled += math.dist(a, b)
        return math.inf

    def _crossings(self, a: Point, b: Point) -> list[float]:
        """Where (0..1 along it, in order) the leg from ``a`` to ``b`` meets the edges (a
        collinear touch: its ends on the leg)."""
        dx, dy = b[0] - a[0], b[1] - a[1]
        found: list[float] = []
        points = self.outline
        for c, d in zip(points, points[1:] + points[:1], strict=True):
            ex, ey = d[0] - c[0], d[1] - c[1]
            denominator = dx * ey - dy * ex
            if denominator == 0.0:
                if segments_cross(a, b, c, d):
                    length_sq = dx * dx + dy * dy or 1.0
                    found += [
                        min(1.0, max(0.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length_sq))
                        for p in (c, d)
                    ]
                continue
            t = ((c[0] - a[0]) * ey - (c[1] - a[1]) * ex) / denominator
            u = ((c[0] - a[0]) * dy - (c[1] - a[1]) * dx) / denominator
            if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0:
                found.append(t)
        return sorted(found)


def may_join(
    zone: ZoneShape,
    holders: Mapping[str, ZonePass | None],
    robot_id: str,
    want: ZonePass,
    standing: bool = False,
) -> bool:
    """Whether ``robot_id`` may hold ``zone`` on pass ``want`` beside its ``holders``
    (robot -> pass; None: it stands in the zone): it stands in the zone (``standing``, or
    recorded so by the zone book -- it goes on, out of it, whatever its pass: held there it
    would block the zone for good), nobody else holds it, or the zone allows convoys and
    every other holder goes the same way (:meth:`ZonePass.same_way`)."""
    others = [p for r, p in holders.items() if r != robot_id]
    if not others or standing or (robot_id in holders and holders[robot_id] is None):
        return True
    return zone.convoys and all(p is not None and want.same_way(p) for p in others)


def declared(site: Site | None) -> tuple[ZoneShape, ...]:
    """The single-robot zones of a site map (a circle as the polygon around it)."""
    if site is None:
        return ()
    return tuple(ZoneShape(z.name, tuple(z.outline()), convoys=z.convoys) for z in site.zones)


def way(
    x: float, y: float, via: Sequence[Point] | Iterable[Point], goal: Point, rest: bool = True
) -> list[Point]:
    """The polyline [m] a robot at (x, y) drives: through the via-points ``via`` to
    ``goal`` -- with ``rest``, only those it still has to pass
    (:func:`fleet.core.route.remaining`: a robot under way); else every one of them (a
    robot about to start)."""
    points = list(via)
    if rest and points:
        points = [(float(p[0]), float(p[1])) for p in remaining(points, x, y)]
    return [(x, y), *points, (float(goal[0]), float(goal[1]))]


def entered(zones: Iterable[ZoneShape], path: Sequence[Point]) -> tuple[str, ...]:
    """The names of ``zones`` that ``path`` enters, in the order given."""
    return tuple(z.name for z in zones if z.entered_by(path))


__all__ = ["ZonePass", "ZoneShape", "declared", "entered", "may_join", "way"]
