"""Single-robot zones the service holds for robots, as it holds bays for tasks (pure).

:class:`ZoneBook` knows the fleet's zones (:class:`fleet.core.zones.ZoneShape`: the site
map's and the narrow passages found in the walls) and which robots hold each, with their
passes (:class:`fleet.core.zones.ZonePass`):

* a plan's decision that starts or moves a robot carries the passes of the zones its way
  enters (:mod:`fleet.core.planner.gates`); the ledger applies it only if the robot may hold
  every one of them (:meth:`ZoneBook.can_take`, :func:`fleet.core.zones.may_join`: nobody
  else holds the zone, or -- a zone that allows convoys -- everybody holding it goes the
  same way), then the robot holds them
  (:meth:`ZoneBook.take`);
* every state of a robot: a zone it stands in becomes its own, beside any holder (a robot
  that got there without a plan: lost on its way, an older release, swung in by a stuck
  recovery; it goes no way, so nobody may join it), and a robot standing in a zone may
  always go on, whatever pass it holds (:meth:`ZoneBook.can_take`): holding a robot inside
  a zone for that zone blocks the zone's holders for good -- seen on case III with four
  robots, a robot held in the gap for 100 s while the gap's holder stood at its mouth, and
  in the corridor, a convoy's leader held at the far mouth in front of its followers; a
  zone it holds is given back once it stands outside it and the
  rest of its way does not enter it (:meth:`ZoneBook.observe`) -- unless that way is no
  path: a leg of it passes through an obstacle's body grown by the robot's radius (the law
  and Eq. (27) will take the robot round the post, perhaps through the zone: a robot swung
  wide of a passage's mouth, whose straight line to its goal cuts past a post, keeps the
  passage); a robot standing in a zone keeps it, whatever its task;
* a robot removed from the fleet gives back every zone (:meth:`ZoneBook.release_robot`).

Pure and not thread-safe: the task ledger keeps it and the service calls it under its lock.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.geometry import segments_distance
from fleet.core.planner.config import PlannerConfig
from fleet.core.types import FloatArray
from fleet.core.wire import Obstacle
from fleet.core.zones import Point, ZonePass, ZoneShape, declared, may_join
from fleet.io.settings import Settings

#: Zone -> the robots holding it, each with its pass (None: it stands in the zone).
Holders = Mapping[str, Mapping[str, ZonePass | None]]
#: An obstacle's body as the zone book sees it: the segment (a post: both ends equal) and
#: its radius [m], the body's grown by the robots' radius.
Body = tuple[Point, Point, float]


def fleet_zones(settings: Settings, obstacles: Sequence[Obstacle]) -> tuple[ZoneShape, ...]:
    """The fleet's single-robot zones: the site map's, then (``settings.narrow_passages``)
    the passages ``obstacles`` make too narrow for two robots of the host's profile to pass
    (:mod:`fleet.core.planner.passages`). The one rule for the service, the offline fleet
    and the benchmark's floors."""
    zones = declared(settings.site)
    if not settings.narrow_passages or not obstacles:
        return zones
    # shapely on first use: the fleet host's package (a robot install imports the service's
    # modules for its command line but never runs a service)
    from fleet.core.planner.passages import narrow_passages

    radius = settings.profile.radius
    clearance = PlannerConfig().route_clearance(radius, settings.safety.contact_margin_m)
    return zones + narrow_passages(obstacles, clearance, radius)


def zone_bodies(settings: Settings, obstacles: Sequence[Obstacle]) -> list[Body]:
    """The obstacles' bodies grown by the host profile's radius, for the zone book (a way
    through one is no path)."""
    radius = settings.profile.radius
    return [((o.x, o.y), o.far_end, o.body_radius + radius) for o in obstacles]


def _boxes(bodies: Sequence[Body]) -> FloatArray:
    """(M, 4) each body's bounding box [m]: min x, min y, max x, max y."""
    out = np.empty((len(bodies), 4))
    for k, ((x0, y0), (x1, y1), radius) in enumerate(bodies):
        out[k] = (
            min(x0, x1) - radius,
            min(y0, y1) - radius,
            max(x0, x1) + radius,
            max(y0, y1) + radius,
        )
    return out


def _through_a_body(way: Sequence[Point], bodies: Sequence[Body], boxes: FloatArray) -> bool:
    """Whether a leg of ``way`` passes through one of ``bodies`` (it is no path); only the
    bodies whose bounding box (``boxes``, :func:`_boxes`) meets the leg's are measured."""
    for (ax, ay), (bx, by) in itertools.pairwise(way):
        near = (
            (boxes[:, 0] <= max(ax, bx))
            & (boxes[:, 2] >= min(ax, bx))
            & (boxes[:, 1] <= max(ay, by))
            & (boxes[:, 3] >= min(ay, by))
        )
        for k in np.flatnonzero(near):
            start, end, radius = bodies[int(k)]
            if segments_distance((ax, ay), (bx, by), start, end) < radius:
                return True
    return False


@dataclass(frozen=True)
class ZoneState:
    """A zone as the API shows it: its shape, the robots holding it and their tasks."""

    zone: ZoneShape
    robot_ids: tuple[str, ...] = ()
    task_ids: tuple[str, ...] = ()


class ZoneBook:
    """Who holds which single-robot zone (see the module docstring)."""

    def __init__(self, shapes: Iterable[ZoneShape] = ()) -> None:
        self._shapes: dict[str, ZoneShape] = {}
        self._bodies: tuple[Body, ...] = ()
        self._boxes = _boxes(())
        self._holders: dict[str, dict[str, ZonePass | None]] = {}  # zone -> robot -> pass
        self._held: dict[str, set[str]] = {}  # robot -> zones
        self._inside: dict[str, frozenset[str]] = {}  # robot -> zones it last stood in
        self.set_zones(shapes)

    # -- the zones ---------------------------------------------------------------------

    def set_zones(self, shapes: Iterable[ZoneShape], bodies: Iterable[Body] = ()) -> None:
        """The fleet's zones from now on, and the obstacles' ``bodies`` (each grown by the
        robots' radius); holders of zones that are gone are forgotten."""
        self._shapes = {z.name: z for z in shapes}
        self._bodies = tuple(bodies)
        self._boxes = _boxes(self._bodies)
        for name in [n for n in self._holders if n not in self._shapes]:
            for robot in list(self._holders[name]):
                self._drop(name, robot)
        self._inside = {
            robot: kept
            for robot, zones in self._inside.items()
            if (kept := zones & self._shapes.keys())
        }

    @property
    def shapes(self) -> tuple[ZoneShape, ...]:
        return tuple(self._shapes.values())

    def __bool__(self) -> bool:
        return bool(self._shapes)

    # -- holders -----------------------------------------------------------------------

    def holders(self) -> dict[str, dict[str, ZonePass | None]]:
        """Zone -> robot -> its pass, for every zone held (a copy)."""
        return {z: dict(h) for z, h in self._holders.items()}

    def holding(self, zone: str) -> tuple[str, ...]:
        """The robots holding ``zone`` (in the order they took it)."""
        return tuple(self._holders.get(zone, ()))

    def held_by(self, robot_id: str) -> frozenset[str]:
        return frozenset(self._held.get(robot_id, ()))

    def can_take(self, robot_id: str, passes: Iterable[ZonePass]) -> bool:
        """Whether ``robot_id`` may hold every zone of ``passes``
        (:func:`fleet.core.zones.may_join`, standing in it where :meth:`observe` last saw
        it; a zone gone since the plan counts as free)."""
        inside = self._inside.get(robot_id, frozenset())
        return all(
            p.zone not in self._shapes
            or may_join(
                self._shapes[p.zone],
                self._holders.get(p.zone, {}),
                robot_id,
                p,
                standing=p.zone in inside,
            )
            for p in passes
        )

    def take(self, robot_id: str, passes: Iterable[ZonePass]) -> bool:
        """``robot_id`` holds the (known) zones of ``passes`` (checked by the caller with
        :meth:`can_take`); whether that changed anything."""
        changed = False
        for p in passes:
            if p.zone in self._shapes and robot_id not in self._holders.get(p.zone, {}):
                self._hold(p.zone, robot_id, p)
                changed = True
        return changed

    def _hold(self, zone: str, robot_id: str, how: ZonePass | None) -> None:
        self._holders.setdefault(zone, {})[robot_id] = how
        self._held.setdefault(robot_id, set()).add(zone)

    def observe(
        self, robot_id: str, x: float, y: float, way: Callable[[], Sequence[Point]] | None
    ) -> bool:
        """A robot is at (x, y) [m]; ``way`` gives the rest of its way (None: it has no
        task). Takes the free zones it stands in and gives back those it has left (see the
        module docstring); whether any holder changed."""
        if not self._shapes:
            return False
        changed = False
        inside = frozenset(n for n, shape in self._shapes.items() if shape.contains(x, y))
        if inside:
            self._inside[robot_id] = inside
        else:
            self._inside.pop(robot_id, None)
        for name in inside:
            if robot_id not in self._holders.get(name, {}):
                self._hold(name, robot_id, None)
                changed = True
        mine = self._held.get(robot_id)
        if not mine:
            return changed
        rest: Sequence[Point] | None = None
        for name in sorted(mine):
            if name in inside:
                continue
            shape = self._shapes[name]
            if way is not None:
                if rest is None:
                    rest = way()
                if shape.entered_by(rest) or _through_a_body(rest, self._bodies, self._boxes):
                    continue
            self._drop(name, robot_id)
            changed = True
        return changed

    def release_robot(self, robot_id: str) -> bool:
        """``robot_id`` left the fleet: every zone it held is free of it; whether it held
        any."""
        zones = list(self._held.get(robot_id, ()))
        self._inside.pop(robot_id, None)
        for z in zones:
            self._drop(z, robot_id)
        return bool(zones)

    def _drop(self, zone: str, robot_id: str) -> None:
        holders = self._holders.get(zone)
        if holders is not None:
            holders.pop(robot_id, None)
            if not holders:
                del self._holders[zone]
        zones = self._held.get(robot_id)
        if zones is not None:
            zones.discard(zone)
            if not zones:
                del self._held[robot_id]

    def __len__(self) -> int:
        """How many zones are held."""
        return len(self._holders)
