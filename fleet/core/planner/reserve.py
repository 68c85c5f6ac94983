"""Prioritised planning on a reservation table of solo predictions (pure, no simulation).

A seed for the rollout search (:mod:`fleet.core.planner.search`) that already staggers
the robots of a cluster. Robots are placed one at a time, each against the space-time
paths of those placed before it:

* robots under way that keep what they do come first, with their current law and delay;
* then the others, longest solo trip first (they decide the makespan);
* each takes the option -- a law it may use and a start delay from ``delays`` -- that
  arrives first (delay + solo time) among those whose solo path, shifted by the delay
  (standing at its start meanwhile), stays at least ``reach`` [m] from every placed path
  at the same sample time (one sample either side) and from every standing robot;
* a robot with no such option takes the one whose first conflict comes latest.

Paths are the scene's solo predictions (each robot alone, static obstacles, no peers),
sampled every ``period`` [s]; a robot that arrived stays at its goal. The repulsion of
Eq. (27) bends real paths, which is why the result is only a seed: rollouts verify it and
repair what is left.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet.core.planner.scene import UNDER_WAY, Candidate, Fleet
from fleet.core.types import FloatArray


def _shifted(path: FloatArray, shift: int, length: int) -> FloatArray:
    """``path`` (T, 2) delayed by ``shift`` samples (standing at its start), to ``length``."""
    out = np.empty((length, 2))
    head = min(shift, length)
    out[:head] = path[0]
    body = path[: max(length - head, 0)]
    out[head : head + body.shape[0]] = body
    out[head + body.shape[0] :] = path[-1]
    return out


def _first_conflict(
    path: FloatArray, placed: FloatArray, standing: FloatArray, reach: float, stand_reach: float
) -> int:
    """First sample index where ``path`` (L, 2) comes within ``reach`` of a placed path
    (P, L, 2) at about the same time, or ``stand_reach`` of a standing robot; L if none."""
    length = path.shape[0]
    hit = np.zeros(length, dtype=bool)
    if placed.shape[0]:  # only placed paths whose box comes near this one's
        lo, hi = path.min(axis=0) - reach, path.max(axis=0) + reach
        near = ((placed.max(axis=1) >= lo) & (placed.min(axis=1) <= hi)).all(axis=1)
        placed = placed[near]
    if placed.shape[0]:
        for off in (-1, 0, 1):
            idx = np.clip(np.arange(length) + off, 0, length - 1)
            d = placed[:, idx] - path[None]
            hit |= ((d * d).sum(axis=2) < reach * reach).any(axis=0)
    if standing.shape[0]:
        d = path[:, None, :] - standing[None]
        hit |= ((d * d).sum(axis=2) < stand_reach * stand_reach).any(axis=1)
    return int(np.argmax(hit)) if hit.any() else length


def reservation(
    fleet: Fleet,
    movers: Sequence[int],
    standing: Sequence[int],
    delays: Sequence[float],
    reach: float,
    stand_reach: float,
) -> tuple[Candidate, FloatArray]:
    """The prioritised candidate for ``movers`` (see the module docstring) and its paths
    (k, L, 2), sampled like the solo predictions."""
    m = fleet.movers
    idx = np.asarray(movers, dtype=np.int64)
    keep = fleet.keep(movers)
    keep.hold[:] = False  # every robot gets a way to go; the search holds if it must
    times = fleet.solo_times
    period = float(times[1] - times[0]) if times.size > 1 else 1.0
    shifts = [(d, round(d / period)) for d in (0.0, *delays)]
    length = times.size + max(s for _, s in shifts)
    solo = np.where(np.isfinite(fleet.solo_time[idx]), fleet.solo_time[idx], np.inf)
    fastest = np.min(np.where(m.allowed[idx], solo, np.inf), axis=1)
    kept = (m.kind[idx] == UNDER_WAY) & ~m.keep_hold[idx]
    order = sorted(range(idx.size), key=lambda p: (not kept[p], -fastest[p], p))
    fixed = fleet.standing_xy[np.asarray(standing, dtype=np.int64)].reshape(-1, 2)
    placed: list[FloatArray] = []
    for p in order:
        i = int(idx[p])
        if kept[p]:
            options = [(int(keep.law[p]), float(keep.delay[p]))]
        else:
            options = [(law, d) for law in (0, 1) if m.allowed[i, law] for d, _ in shifts]
            options.sort(key=lambda o: o[1] + solo[p, o[0]])
        stack = np.stack(placed) if placed else np.zeros((0, length, 2))
        best, best_at = options[0], -1
        for law, d in options:
            path = _shifted(fleet.solo_xy[:, i, law], round(d / period), length)
            at = _first_conflict(path, stack, fixed, reach, stand_reach)
            if at == length:
                best, best_at = (law, d), at
                break
            if at > best_at:
                best, best_at = (law, d), at
        law, d = best
        keep.law[p], keep.delay[p] = law, d
        placed.append(_shifted(fleet.solo_xy[:, i, law], round(d / period), length))
    paths = np.zeros((idx.size, length, 2))
    for p, path in zip(order, placed, strict=True):
        paths[p] = path
    return keep, paths


__all__ = ["reservation"]
