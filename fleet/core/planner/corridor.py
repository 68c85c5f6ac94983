"""Predicted corridors: where a robot should be, and when, under its plan (pure).

A corridor is the robot's predicted path sampled as ``(t [s], x [m], y [m])`` points, ``t``
counted from the moment the plan reaches the robots (a start delay shows as samples at the
start; after arrival the robot stays at its last sample). The service re-plans when a robot
*leaves* its corridor: at robot time ``t`` after the plan, its observed position is farther
than ``radius_m`` from every segment of the corridor that overlaps ``[t - slack_s,
t + slack_s]`` -- a robot a little late or early (latency, noise, a peer it met a bit
differently) is still on it; one that took the other way round, or stands where it should
drive, is not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fleet.core.types import FloatArray

Corridor = tuple[tuple[float, float, float], ...]


def sample_corridor(times: FloatArray, xy: FloatArray, every: int) -> Corridor:
    """Every ``every``-th sample of a recorded path (``times`` (T,), ``xy`` (T, 2)) and the
    last one, as ``(t, x, y)`` rounded to the millimetre and millisecond."""
    n = times.shape[0]
    if n == 0:
        return ()
    picks = list(range(0, n, max(every, 1)))
    if picks[-1] != n - 1:
        picks.append(n - 1)
    rows = np.column_stack([times[picks], xy[picks]]).round(3).tolist()
    return tuple((t, x, y) for t, x, y in rows)


def corridor_distance(
    corridor: Sequence[tuple[float, float, float]], t: float, x: float, y: float, slack_s: float
) -> float:
    """Distance [m] from ``(x, y)`` to the corridor between ``t - slack_s`` and
    ``t + slack_s`` (0 for an empty corridor: there is nothing to leave)."""
    if not corridor:
        return 0.0
    c = np.asarray(corridor, dtype=np.float64)
    if c.shape[0] == 1 or t - slack_s >= c[-1, 0]:
        return math.hypot(x - c[-1, 1], y - c[-1, 2])
    t0, t1 = c[:-1, 0], c[1:, 0]
    live = (t1 >= t - slack_s) & (t0 <= t + slack_s)
    if not live.any():
        first = 0 if t + slack_s < c[0, 0] else -1
        return math.hypot(x - c[first, 1], y - c[first, 2])
    a, b = c[:-1, 1:][live], c[1:, 1:][live]
    ab = b - a
    length2 = (ab * ab).sum(axis=1)
    p = np.array([x, y])
    s = np.clip(((p - a) * ab).sum(axis=1) / np.maximum(length2, 1e-18), 0.0, 1.0)
    nearest = a + s[:, None] * ab
    return float(np.sqrt(((nearest - p) ** 2).sum(axis=1)).min())


def left_corridor(
    corridor: Sequence[tuple[float, float, float]],
    t: float,
    x: float,
    y: float,
    radius_m: float,
    slack_s: float,
) -> bool:
    """Whether a robot at ``(x, y)`` at ``t`` [s after the plan] has left its corridor."""
    return corridor_distance(corridor, t, x, y, slack_s) > radius_m


__all__ = ["Corridor", "corridor_distance", "left_corridor", "sample_corridor"]
