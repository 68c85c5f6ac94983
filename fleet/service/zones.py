"""Single-robot zones the service holds for robots, as it holds bays for tasks (pure).

:class:`ZoneBook` knows the fleet's zones (:class:`fleet.core.zones.ZoneShape`: the site
map's and the narrow passages found in the walls) and which robot holds each:

* a plan's decision that starts or moves a robot carries the zones its way enters
  (:mod:`fleet.core.planner.gates`); the ledger applies it only if none of them is held by
  another robot (:meth:`ZoneBook.can_take`), then the robot holds them (:meth:`take`);
* every state of a robot: a zone it stands in that nobody holds becomes its own (a robot
  that got there without a plan: lost on its way, an older release); a zone it holds is
  given back once it stands outside it and the rest of its way does not enter it
  (:meth:`observe`); a robot standing in a zone keeps it, whatever its task;
* a robot removed from the fleet gives back every zone (:meth:`release_robot`).

Pure and not thread-safe: the task ledger keeps it and the service calls it under its lock.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

from fleet.core.zones import Point, ZoneShape


@dataclass(frozen=True)
class ZoneState:
    """A zone as the API shows it: its shape, the robot holding it and that robot's task."""

    zone: ZoneShape
    robot_id: str | None = None
    task_id: str | None = None


class ZoneBook:
    """Who holds which single-robot zone (see the module docstring)."""

    def __init__(self, shapes: Iterable[ZoneShape] = ()) -> None:
        self._shapes: dict[str, ZoneShape] = {}
        self._holder: dict[str, str] = {}  # zone -> robot
        self._held: dict[str, set[str]] = {}  # robot -> zones
        self.set_zones(shapes)

    # -- the zones ---------------------------------------------------------------------

    def set_zones(self, shapes: Iterable[ZoneShape]) -> None:
        """The fleet's zones from now on; holders of zones that are gone are forgotten."""
        self._shapes = {z.name: z for z in shapes}
        for name in [n for n in self._holder if n not in self._shapes]:
            self._drop(name)

    @property
    def shapes(self) -> tuple[ZoneShape, ...]:
        return tuple(self._shapes.values())

    def __bool__(self) -> bool:
        return bool(self._shapes)

    # -- holders -----------------------------------------------------------------------

    def holders(self) -> Mapping[str, str]:
        """Zone -> the robot holding it (a copy)."""
        return dict(self._holder)

    def holder(self, zone: str) -> str | None:
        return self._holder.get(zone)

    def held_by(self, robot_id: str) -> frozenset[str]:
        return frozenset(self._held.get(robot_id, ()))

    def can_take(self, robot_id: str, zones: Iterable[str]) -> bool:
        """Whether ``robot_id`` may hold every one of ``zones`` (free or its own; an
        unknown zone, gone since the plan, counts as free)."""
        return all(self._holder.get(z, robot_id) == robot_id for z in zones)

    def take(self, robot_id: str, zones: Iterable[str]) -> bool:
        """``robot_id`` holds ``zones`` (known ones, free or its own); whether that
        changed anything."""
        changed = False
        for z in zones:
            if z in self._shapes and z not in self._holder:
                self._holder[z] = robot_id
                self._held.setdefault(robot_id, set()).add(z)
                changed = True
        return changed

    def observe(
        self, robot_id: str, x: float, y: float, way: Callable[[], Sequence[Point]] | None
    ) -> bool:
        """A robot is at (x, y) [m]; ``way`` gives the rest of its way (None: it has no
        task). Takes the free zones it stands in and gives back those it has left (see the
        module docstring); whether any holder changed."""
        if not self._shapes:
            return False
        changed = False
        for name, shape in self._shapes.items():
            if name not in self._holder and shape.contains(x, y):
                changed |= self.take(robot_id, (name,))
        mine = self._held.get(robot_id)
        if not mine:
            return changed
        rest: Sequence[Point] | None = None
        for name in sorted(mine):
            shape = self._shapes[name]
            if shape.contains(x, y):
                continue
            if way is not None:
                if rest is None:
                    rest = way()
                if shape.entered_by(rest):
                    continue
            self._drop(name)
            changed = True
        return changed

    def release_robot(self, robot_id: str) -> bool:
        """``robot_id`` left the fleet: every zone it held is free; whether it held any."""
        zones = self._held.pop(robot_id, set())
        for z in zones:
            self._holder.pop(z, None)
        return bool(zones)

    def _drop(self, zone: str) -> None:
        robot = self._holder.pop(zone, None)
        if robot is not None:
            zones = self._held.get(robot)
            if zones is not None:
                zones.discard(zone)
                if not zones:
                    del self._held[robot]

    def __len__(self) -> int:
        return len(self._holder)
