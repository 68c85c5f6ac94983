"""Named parking bays of the site map: which active task reserves which bay.

A bay is reserved by exactly one active task (``TaskRequest.bay``) from the moment the
task is accepted until it is final; a second task for the same bay is refused
(:class:`fleet.core.tasks.BayTaken`, 409). :meth:`BayBook.state` says what the dashboard
shows: ``reserved`` (by an active task), ``occupied`` (a robot with no active task stands
within ``OCCUPIED_RADIUS_M`` of its pose) or ``free``.

Pure and not thread-safe: the task ledger (:mod:`fleet.service.ledger`) keeps it with its
indexes -- a bay is held when a task is reserved or becomes active, released when the task
becomes final (or its reservation is given back) -- and the service calls it under its lock.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

from fleet.core.site import Bay, Site
from fleet.core.tasks import BayNotFound, BayTaken, RobotView, Task

#: A robot standing this close to a bay's pose [m] occupies it.
OCCUPIED_RADIUS_M = 0.5

BayStatus = Literal["free", "reserved", "occupied"]


@dataclass(frozen=True)
class BayState:
    bay: Bay
    status: BayStatus
    task_id: str | None = None  # the reserving task
    robot_id: str | None = None  # the robot driving there, or parked in it


class BayBook:
    """Reservations of the bays of one site (none without a site)."""

    def __init__(self, site: Site | None) -> None:
        self.site = site
        self._holder: dict[str, str] = {}  # bay -> task id
        self._bay_of: dict[str, str] = {}  # task id -> bay

    def _site(self) -> Site:
        if self.site is None:
            raise BayNotFound("this fleet has no site map: start it with a site file (--site)")
        return self.site

    def bay(self, name: str) -> Bay:
        bay = self._site().bay(name)
        if bay is None:
            raise BayNotFound(f"bay {name} not found")
        return bay

    def candidates(self, name: str | None, group: str | None) -> list[Bay]:
        """The named bay, or the bays of ``group`` not reserved now (in file order)."""
        if name is not None:
            return [self.bay(name)]
        assert group is not None
        bays = self._site().group(group)
        if not bays:
            raise BayNotFound(f"bay group {group} not found")
        free = [b for b in bays if b.name not in self._holder]
        if not free:
            raise BayTaken(f"every bay of group {group} is taken")
        return free

    def check(self, task: Task) -> None:
        """Raise :class:`BayTaken` if ``task``'s bay is reserved by another task."""
        bay = task.request.bay
        if bay is None:
            return
        holder = self._holder.get(bay)
        if holder is not None and holder != task.id:
            raise BayTaken(f"bay {bay} is taken by task {holder}")

    def hold(self, task: Task) -> None:
        """Reserve ``task``'s bay (if it names one) for it."""
        bay = task.request.bay
        if bay is not None:
            self._holder[bay] = task.id
            self._bay_of[task.id] = bay

    def release(self, task_id: str) -> None:
        """Give back the bay ``task_id`` holds, if any."""
        bay = self._bay_of.pop(task_id, None)
        if bay is not None and self._holder.get(bay) == task_id:
            del self._holder[bay]

    def __len__(self) -> int:
        return len(self._holder)

    def holder(self, bay: str) -> str | None:
        """The task that reserves ``bay``, if any."""
        return self._holder.get(bay)

    def states(self, active: Mapping[str, Task], robots: Iterable[RobotView]) -> list[BayState]:
        """Every bay with its state; ``active`` non-final tasks by id, ``robots`` the roster."""
        if self.site is None:
            return []
        busy = {t.robot_id for t in active.values() if t.robot_id is not None}
        parked = [r for r in robots if r.robot_id not in busy]
        out = []
        for bay in self.site.bays:
            holder = self._holder.get(bay.name)
            if holder is not None:
                task = active.get(holder)
                out.append(
                    BayState(bay, "reserved", holder, None if task is None else task.robot_id)
                )
                continue
            robot = next(
                (
                    r.robot_id
                    for r in parked
                    if math.hypot(r.pose.x - bay.pose.x, r.pose.y - bay.pose.y) <= OCCUPIED_RADIUS_M
                ),
                None,
            )
            out.append(BayState(bay, "free" if robot is None else "occupied", None, robot))
        return out
