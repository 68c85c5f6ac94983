"""The smallest separation seen between two robots (pure; fed with robot positions).

:class:`SeparationTracker` keeps the latest centre of every robot in a uniform grid of
``cutoff``-sized cells; each update compares the moved robot with the robots in the nine
neighbouring cells only, so it costs O(robots nearby), not O(fleet). Separations at or
above ``cutoff`` are not tracked: the minimum stays ``inf`` until two robots come closer
than that (a fleet-wide minimum of 20 m says nothing an operator needs).
"""

from __future__ import annotations

import math


class SeparationTracker:
    """Running minimum of the centre distance [m] between any two robots."""

    def __init__(self, cutoff: float = 5.0) -> None:
        if not (cutoff > 0 and math.isfinite(cutoff)):
            raise ValueError("cutoff must be a positive finite distance")
        self.cutoff = float(cutoff)
        self.minimum = math.inf
        self.pair: tuple[str, str] | None = None  # robots of the minimum
        self._where: dict[str, tuple[float, float, tuple[int, int]]] = {}
        self._cells: dict[tuple[int, int], set[str]] = {}

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        return (math.floor(x / self.cutoff), math.floor(y / self.cutoff))

    def update(self, robot_id: str, x: float, y: float) -> float:
        """Record a robot's centre [m]; returns the minimum seen so far."""
        if not (math.isfinite(x) and math.isfinite(y)):
            return self.minimum
        cell = self._cell(x, y)
        old = self._where.get(robot_id)
        if old is not None and old[2] != cell:
            self._forget_cell(robot_id, old[2])
        self._where[robot_id] = (x, y, cell)
        self._cells.setdefault(cell, set()).add(robot_id)
        i, j = cell
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                for other in self._cells.get((i + di, j + dj), ()):
                    if other == robot_id:
                        continue
                    ox, oy, _ = self._where[other]
                    d = math.hypot(x - ox, y - oy)
                    if d < self.minimum and d < self.cutoff:
                        self.minimum = d
                        self.pair = (min(robot_id, other), max(robot_id, other))
        return self.minimum

    def remove(self, robot_id: str) -> None:
        """Forget a robot (e.g. decommissioned): it no longer counts."""
        old = self._where.pop(robot_id, None)
        if old is not None:
            self._forget_cell(robot_id, old[2])

    def _forget_cell(self, robot_id: str, cell: tuple[int, int]) -> None:
        members = self._cells.get(cell)
        if members is not None:
            members.discard(robot_id)
            if not members:
                del self._cells[cell]
