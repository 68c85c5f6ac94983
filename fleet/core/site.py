"""The site map: the yard, static obstacles, keep-out zones and named parking bays (pure).

A :class:`Site` is what an operator writes in a site file (TOML or JSON, loaded by
:mod:`fleet.io.site_file`, which names the line of every error). Frame: the world frame of
the fleet, x and y in metres, theta in radians counter-clockwise from +x.

* ``yard`` -- the rectangle goals must lie in (replaces ``Settings.yard``);
* ``obstacles`` -- static circular obstacles (posts) with their body and influence radius
  (the paper's Section 6; robots are repelled by Eq. (27) inside it, goals must lie outside
  it);
* ``walls`` -- polylines and polygons with a body (half their thickness): every edge is a
  segment obstacle the robots' safety filter keeps clear of (:meth:`Site.static_obstacles`);
* ``keep_out`` -- named zones (polygon, rectangle or circle) where no goal may lie, nor a
  parked robot's body. They restrict goals; robots are not steered around them: put a wall
  or a post where robots must not drive through;
* ``bays`` -- named parking postures, optionally in a ``group`` such as ``charging``; a
  task may ask for a bay by name or for any free bay of a group;
* ``zones`` -- named single-robot zones (polygon, rectangle or circle): gates and narrow
  aisles one robot at a time drives through (:class:`Zone`; the fleet holds them like
  bays, :mod:`fleet.core.zones`). Narrow passages the walls make are found as well
  (:mod:`fleet.core.planner.passages`);
* ``lanes`` -- polylines robots drive along, one-way or two-way: with lanes, routes follow
  them from a lane point a robot sees to one its bay's approach sees
  (:mod:`fleet.core.planner.lanes`); without, routes are found in the free space.

:meth:`Site.problems` checks what needs the fleet's settings (robot radius, peer
influence radius): every bay a valid goal, and bays far enough apart to be used together.
"""

from __future__ import annotations

import itertools
import math
from typing import Annotated, ClassVar, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

from fleet.core.geometry import (
    first_self_crossing,
    inside_polygon,
    segment_distance,
    segments_distance,
)
from fleet.core.params import SafetyConfig
from fleet.core.wire import Obstacle, Pose

Coordinate = Annotated[float, Field(allow_inf_nan=False)]
Name = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")]
Point = tuple[Coordinate, Coordinate]

Loc = tuple[str | int, ...]


class SiteError(ValueError):
    """A site inconsistency, with the location (``loc``, as pydantic's) of what causes it;
    the file loader turns it into a line number."""

    def __init__(self, message: str, loc: Loc = ()) -> None:
        super().__init__(message)
        self.loc = loc


#: Bounds that keep a site file from growing without limit.
MAX_BAYS = 10_000
MAX_ZONES = 1_000
MAX_VERTICES = 256
#: Posts plus wall segments: one obstacle set (:class:`fleet.core.wire.ObstacleSet`).
MAX_OBSTACLES = 1000


class _Strict(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Rect(_Strict):
    """An axis-aligned rectangle [m]."""

    xmin: Coordinate
    xmax: Coordinate
    ymin: Coordinate
    ymax: Coordinate

    @model_validator(mode="after")
    def _not_empty(self) -> Self:
        if not (self.xmin < self.xmax and self.ymin < self.ymax):
            raise ValueError("a rectangle needs xmin < xmax and ymin < ymax")
        return self

    def as_tuple(self) -> tuple[float, float, float, float]:
        return (self.xmin, self.xmax, self.ymin, self.ymax)

    def contains(self, x: float, y: float) -> bool:
        return self.xmin <= x <= self.xmax and self.ymin <= y <= self.ymax


class Yard(Rect):
    """The yard rectangle [m]: every goal lies in it."""


class Circle(_Strict):
    x: Coordinate
    y: Coordinate
    radius: Annotated[float, Field(gt=0, allow_inf_nan=False)]


class Area(_Strict):
    """A region of the floor: exactly one of ``polygon`` (vertices in order, at least 3),
    ``rect`` or ``circle``."""

    polygon: Annotated[list[Point], Field(min_length=3, max_length=MAX_VERTICES)] | None = None
    rect: Rect | None = None
    circle: Circle | None = None

    #: What the area is called in messages ("keep-out zone", "single-robot zone").
    kind: ClassVar[str] = "area"

    @model_validator(mode="after")
    def _one_shape(self) -> Self:
        given = [s for s in (self.polygon, self.rect, self.circle) if s is not None]
        if len(given) != 1:
            raise ValueError(f"a {self.kind} needs exactly one of polygon, rect or circle")
        if self.polygon is not None:
            crossing = first_self_crossing(self.polygon, closed=True)
            if crossing is not None:
                i, j = crossing
                raise ValueError(f"polygon: edges {i} and {j} cross (a polygon must be simple)")
            if _polygon_area(self.polygon) == 0.0:
                raise ValueError("the polygon has no area (collinear or repeated vertices)")
        return self

    def vertices(self) -> list[tuple[float, float]]:
        """The outline as a polygon (a circle has none: empty)."""
        if self.polygon is not None:
            return [(float(x), float(y)) for x, y in self.polygon]
        if self.rect is not None:
            r = self.rect
            return [(r.xmin, r.ymin), (r.xmax, r.ymin), (r.xmax, r.ymax), (r.xmin, r.ymax)]
        return []

    def outline(self, chords: int = 24) -> list[tuple[float, float]]:
        """The outline as a polygon; a circle as the regular polygon of ``chords`` sides
        around it (its edges touch the circle: the polygon contains it)."""
        if self.circle is None:
            return self.vertices()
        c = self.circle
        grown = c.radius / math.cos(math.pi / chords)
        return [
            (c.x + grown * math.cos(2 * math.pi * k / chords),
             c.y + grown * math.sin(2 * math.pi * k / chords))
            for k in range(chords)
        ]  # fmt: skip

    def distance(self, x: float, y: float) -> float:
        """Distance [m] from (x, y) to the area; 0 inside or on its edge."""
        if self.circle is not None:
            c = self.circle
            return max(0.0, math.hypot(x - c.x, y - c.y) - c.radius)
        vertices = self.vertices()
        if inside_polygon(vertices, x, y):
            return 0.0
        return min(
            segment_distance(x, y, a, b)
            for a, b in zip(vertices, vertices[1:] + vertices[:1], strict=True)
        )


class KeepOutZone(Area):
    """A named zone where no goal may lie (see the module docstring)."""

    kind: ClassVar[str] = "keep-out zone"
    name: Name


class Zone(Area):
    """A named single-robot zone (a gate, a narrow aisle): one robot at a time drives in it.

    The fleet grants a zone to one robot before it starts (or goes on) on a way through
    it, and takes it back once that robot has left it and its way no longer enters it; a
    robot standing in it (lost, idle, its task ended) keeps it until it leaves or is
    removed. No goal may lie in it (a parked robot would hold it for ever). With
    ``convoys``, robots going the same way may hold it together, following each other."""

    kind: ClassVar[str] = "single-robot zone"
    name: Name
    #: robots going the same way may follow each other through it (a one-way-at-a-time
    #: aisle); default: one robot at a time
    convoys: bool = False


#: A wall's body radius (half its thickness) [m] when the site file gives none.
DEFAULT_WALL_BODY_M = 0.05
#: A wall's influence radius of Eq. (27) [m] when none is given: no more than a robot's
#: centre can come near a wall anyway, so by default walls act through the safety filter
#: only (no repulsion that would slow robots driving along them).
DEFAULT_WALL_INFLUENCE_M = 0.3


class Wall(_Strict):
    """A wall: the segments of a polyline through ``points`` (``closed``: a polygon, the
    last point joined to the first), each a body of radius ``body`` (half the wall's
    thickness) [m] that robots keep ``contact_margin_m`` from, and ``radius`` [m], the
    influence radius of Eq. (27) around it."""

    name: Name | None = None
    points: Annotated[list[Point], Field(min_length=2, max_length=MAX_VERTICES)]
    closed: bool = False
    body: Annotated[float, Field(ge=0, le=5.0, allow_inf_nan=False)] = DEFAULT_WALL_BODY_M
    radius: Annotated[float, Field(gt=0, le=20.0, allow_inf_nan=False)] = DEFAULT_WALL_INFLUENCE_M

    @model_validator(mode="after")
    def _simple(self) -> Self:
        if self.body > self.radius:
            raise ValueError(f"body: {self.body} m exceeds the influence radius {self.radius} m")
        if self.closed and len(self.points) < 3:
            raise ValueError("points: a closed wall (a polygon) needs at least 3 points")
        n = len(self.points)
        for i, (a, b) in enumerate(self.edges()):
            if a == b:
                raise ValueError(f"points: point {(i + 1) % n} repeats point {i} (an empty edge)")
        crossing = first_self_crossing(self.points, self.closed)
        if crossing is not None:
            i, j = crossing
            raise ValueError(
                f"points: the wall crosses itself (edge {i}, from point {i}, and edge {j}, "
                f"from point {j})"
            )
        return self

    def edges(self) -> list[tuple[Point, Point]]:
        """The wall's edges in order, each (from, to); closed: the last back to the first."""
        n = len(self.points)
        count = n if self.closed else n - 1
        return [(self.points[i], self.points[(i + 1) % n]) for i in range(count)]

    def segments(self) -> list[Obstacle]:
        """The wall as obstacles: one segment per edge."""
        return [
            Obstacle(x=a[0], y=a[1], end=b, radius=self.radius, body=self.body)
            for a, b in self.edges()
        ]


class Lane(_Strict):
    """A lane robots drive along: a polyline through ``points`` [m]; ``one_way``: only from
    the first point towards the last. Lanes meet where they share a point (a junction);
    lanes that cross without sharing one do not meet. When a site has lanes, routes follow
    them (:mod:`fleet.core.planner.lanes`)."""

    name: Name | None = None
    points: Annotated[list[Point], Field(min_length=2, max_length=MAX_VERTICES)]
    one_way: bool = False

    @model_validator(mode="after")
    def _no_empty_leg(self) -> Self:
        for i, (a, b) in enumerate(itertools.pairwise(self.points)):
            if a == b:
                raise ValueError(f"points: point {i + 1} repeats point {i} (an empty leg)")
        return self


class Bay(_Strict):
    """A named parking posture, optionally in a group (e.g. ``charging``)."""

    name: Name
    pose: Pose
    group: Name | None = None


class Site(_Strict):
    """The site map (see the module docstring)."""

    name: Annotated[str, Field(max_length=200)] = "site"
    yard: Yard
    obstacles: Annotated[list[Obstacle], Field(max_length=MAX_OBSTACLES)] = Field(
        default_factory=list
    )
    walls: Annotated[list[Wall], Field(max_length=MAX_ZONES)] = Field(default_factory=list)
    keep_out: Annotated[list[KeepOutZone], Field(max_length=MAX_ZONES)] = Field(
        default_factory=list
    )
    bays: Annotated[list[Bay], Field(max_length=MAX_BAYS)] = Field(default_factory=list)
    zones: Annotated[list[Zone], Field(max_length=MAX_ZONES)] = Field(default_factory=list)
    lanes: Annotated[list[Lane], Field(max_length=MAX_ZONES)] = Field(default_factory=list)

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        names: list[tuple[str, str, list[str]]] = [
            ("bays", "bay", [b.name for b in self.bays]),
            ("keep_out", "keep-out zone", [z.name for z in self.keep_out]),
            ("zones", "single-robot zone", [z.name for z in self.zones]),
        ]
        for field, what, items in names:
            seen: set[str] = set()
            for i, name in enumerate(items):
                if name in seen:
                    raise SiteError(f"two {what}s are named {name!r}", (field, i, "name"))
                seen.add(name)
        count = len(self.obstacles) + sum(len(w.segments()) for w in self.walls)
        if count > MAX_OBSTACLES:
            raise SiteError(
                f"{count} obstacles and wall segments: at most {MAX_OBSTACLES} (one obstacle set)",
                ("walls",),
            )
        for i, bay in enumerate(self.bays):
            if not self.yard.contains(bay.pose.x, bay.pose.y):
                p = bay.pose
                raise SiteError(
                    f"bay {bay.name} at ({p.x:g}, {p.y:g}) is outside the yard", ("bays", i, "pose")
                )
        return self

    def static_obstacles(self) -> list[Obstacle]:
        """Everything static a robot must keep clear of: the posts, then every wall's
        segments (the obstacle set the fleet publishes)."""
        return list(self.obstacles) + [seg for wall in self.walls for seg in wall.segments()]

    def bay(self, name: str) -> Bay | None:
        return next((b for b in self.bays if b.name == name), None)

    def group(self, group: str) -> list[Bay]:
        return [b for b in self.bays if b.group == group]

    def keep_out_at(self, x: float, y: float, margin: float = 0.0) -> KeepOutZone | None:
        """The first keep-out zone within ``margin`` [m] of (x, y), or None."""
        return next((z for z in self.keep_out if z.distance(x, y) <= margin), None)

    def problems(self, robot_radius: float, peer_radius: float) -> list[SiteError]:
        """What makes some bays unusable with these radii [m] (empty: none).

        A bay must lie outside every obstacle's influence zone, more than ``robot_radius``
        from every keep-out and single-robot zone, more than ``peer_radius`` from every
        other bay (two robots parked closer would push each other away by Eq. (27)), and be
        reachable on a route from the other bays (:meth:`_unreachable_bays`).
        """
        out: list[SiteError] = []
        static = self.static_obstacles()
        for i, bay in enumerate(self.bays):
            x, y = bay.pose.x, bay.pose.y
            for obstacle in static:
                d = obstacle.distance(x, y)
                reach = max(obstacle.radius, obstacle.body_radius + robot_radius)
                if d <= reach:
                    what = (
                        f"the obstacle at ({obstacle.x:g}, {obstacle.y:g})"
                        if obstacle.end is None
                        else f"the wall from ({obstacle.x:g}, {obstacle.y:g}) to "
                        f"({obstacle.far_end[0]:g}, {obstacle.far_end[1]:g})"
                    )
                    out.append(
                        SiteError(
                            f"bay {bay.name} lies within {reach:g} m of {what} (distance "
                            f"{d:.2f} m; influence radius {obstacle.radius:g} m, body "
                            f"{obstacle.body_radius:g} m plus a robot's {robot_radius:g} m)",
                            ("bays", i, "pose"),
                        )
                    )
            zone = self.keep_out_at(x, y, robot_radius)
            if zone is not None:
                out.append(
                    SiteError(
                        f"bay {bay.name} is within {robot_radius:g} m of keep-out zone {zone.name}",
                        ("bays", i, "pose"),
                    )
                )
            single = next((z for z in self.zones if z.distance(x, y) <= robot_radius), None)
            if single is not None:
                out.append(
                    SiteError(
                        f"bay {bay.name} is within {robot_radius:g} m of single-robot zone "
                        f"{single.name}: a robot parked there would hold the zone",
                        ("bays", i, "pose"),
                    )
                )
        ordered = sorted(enumerate(self.bays), key=lambda ib: ib[1].pose.x)
        for k, (_, a) in enumerate(ordered):  # sweep on x: only bays within peer_radius in x
            for j, b in ordered[k + 1 :]:
                if b.pose.x - a.pose.x > peer_radius:
                    break
                d = math.hypot(a.pose.x - b.pose.x, a.pose.y - b.pose.y)
                if d <= peer_radius:
                    out.append(
                        SiteError(
                            f"bays {a.name} and {b.name} are {d:.2f} m apart: bays must be more "
                            f"than the peer influence radius {peer_radius:g} m apart",
                            ("bays", j, "pose"),
                        )
                    )
        reported = {p.loc[1] for p in out if len(p.loc) > 1}
        out.extend(self._unreachable_bays(robot_radius, reported))
        out.extend(self._lanes_through_bodies(static, robot_radius))
        return out

    def _lanes_through_bodies(self, static: list[Obstacle], robot_radius: float) -> list[SiteError]:
        """Lane legs that would bring a robot's body within the contact margin of a wall's
        or a post's body (robots drive along them)."""
        margin = SafetyConfig().contact_margin_m
        out = []
        for i, lane in enumerate(self.lanes):
            for k, (a, b) in enumerate(itertools.pairwise(lane.points)):
                for o in static:
                    d = segments_distance(a, b, (o.x, o.y), o.far_end) - o.body_radius
                    if d < robot_radius + margin:
                        what = lane.name or f"lanes[{i}]"
                        out.append(
                            SiteError(
                                f"lane {what}: the leg from point {k} to point {k + 1} passes "
                                f"{max(d, 0.0):.2f} m from the body of the obstacle at "
                                f"({o.x:g}, {o.y:g}): a robot needs {robot_radius + margin:g} m",
                                ("lanes", i, "points", k),
                            )
                        )
                        break
        return out

    def _unreachable_bays(self, robot_radius: float, skip: set[str | int]) -> list[SiteError]:
        """Bays that no route reaches from the site's other bays (its largest group of
        bays that routes join) for robots of ``robot_radius`` [m] keeping the default
        contact margin (:mod:`fleet.core.planner.roadmap`); bays in ``skip`` (indices with
        a problem already) are left out. Only sites with walls; skipped on a machine
        without the route graph's libraries (a robot computer plans nothing)."""
        if not self.walls or len(self.bays) < 2:
            return []
        try:
            from fleet.core.planner.config import PlannerConfig
            from fleet.core.planner.lanes import route_graph
            from fleet.core.route import lane_shapes
        except ModuleNotFoundError:  # shapely / networkx: the fleet host's packages
            return []
        config = PlannerConfig()
        clearance = config.route_clearance(robot_radius, SafetyConfig().contact_margin_m)
        roadmap = route_graph(tuple(self.static_obstacles()), clearance, lane_shapes(self.lanes))
        groups: list[list[int]] = []
        for i, bay in enumerate(self.bays):
            if i in skip:
                continue
            for group in groups:
                first = self.bays[group[0]].pose
                goal = bay.pose.as_tuple()
                if roadmap.route((first.x, first.y), goal, config.approach_m) is not None:
                    group.append(i)
                    break
            else:
                groups.append([i])
        if not groups:
            return []
        main = max(groups, key=len)
        return [
            SiteError(
                f"bay {self.bays[i].name}: no route reaches it from bay "
                f"{self.bays[main[0]].name} (walls close it off from the other bays for a "
                f"robot of radius {robot_radius:g} m)",
                ("bays", i, "pose"),
            )
            for group in groups
            if group is not main
            for i in group
        ]


def _polygon_area(points: list[Point]) -> float:
    return 0.5 * abs(
        sum(
            x0 * y1 - x1 * y0
            for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1], strict=True)
        )
    )
