"""Receding-horizon triggers: when what the robots do departs from what the plan predicted.

Pure functions (the service calls them under or beside its lock):

* :class:`Corridor` -- a decision's predicted path ``(t [s, robot time], x [m], y [m])``
  anchored to the robot's state sequence numbers (one per control tick), and
  :meth:`Corridor.deviation`, the distance between an observed pose and the predicted one
  *at the same robot time* (linear interpolation; before the first sample the first, after
  the last the last: the robot waits, or stands at its goal).
* :func:`close_pairs` -- pairs of robots nearer than a distance, at least one of them
  moving, found with a uniform grid in O(robots) instead of O(robots²).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass
class Corridor:
    """A predicted path of one task revision, and the state ``seq`` at which its t = 0.

    ``origin_seq`` is None until known: for a decision that was sent, the first state that
    acknowledges it marks t = 0; for one that was kept, the snapshot's state plus the lead
    time does. ``tripped`` is set once the robot left it, so one departure triggers one
    re-plan.
    """

    revision: int
    samples: tuple[tuple[float, float, float], ...]
    control_hz: float
    origin_seq: float | None = None
    tripped: bool = False
    _times: list[float] = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        self._times = [s[0] for s in self.samples]

    def robot_time(self, seq: int) -> float | None:
        """Robot seconds since t = 0 of the prediction, for a state with ``seq``."""
        if self.origin_seq is None:
            return None
        return (seq - self.origin_seq) / self.control_hz

    def predicted(self, t: float) -> tuple[float, float]:
        """Predicted (x, y) [m] at robot time ``t`` [s]."""
        s, times = self.samples, self._times
        k = bisect.bisect_right(times, t)
        if k == 0:
            return s[0][1], s[0][2]
        if k >= len(s):
            return s[-1][1], s[-1][2]
        t0, x0, y0 = s[k - 1]
        t1, x1, y1 = s[k]
        a = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
        return x0 + a * (x1 - x0), y0 + a * (y1 - y0)

    def deviation(self, seq: int, x: float, y: float) -> float | None:
        """Distance [m] of the observed (x, y) from the prediction at the state's robot
        time, or None when the time origin is not known yet."""
        t = self.robot_time(seq)
        if t is None or not self.samples:
            return None
        px, py = self.predicted(t)
        return math.hypot(x - px, y - py)


def close_pairs(
    points: Sequence[tuple[str, float, float, bool]], distance: float
) -> set[tuple[str, str]]:
    """Pairs ``(a, b)`` (ids sorted) of points ``(id, x [m], y [m], moving)`` closer than
    ``distance`` [m], at least one of the two moving."""
    if distance <= 0:
        return set()
    cells: dict[tuple[int, int], list[tuple[str, float, float, bool]]] = {}
    for p in points:
        cells.setdefault((math.floor(p[1] / distance), math.floor(p[2] / distance)), []).append(p)
    out: set[tuple[str, str]] = set()
    for (i, j), here in cells.items():
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                there = cells.get((i + di, j + dj))
                if there is None:
                    continue
                for a in here:
                    if not a[3]:
                        continue  # pairs are found from their moving member
                    for b in there:
                        if a[0] != b[0] and math.hypot(a[1] - b[1], a[2] - b[2]) < distance:
                            out.add((a[0], b[0]) if a[0] < b[0] else (b[0], a[0]))
    return out
