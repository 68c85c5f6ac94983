"""Prioritised planning on a reservation table of solo predictions (pure, no simulation).

A seed for the rollout search (:mod:`fleet.core.planner.search`) that already staggers
the robots of a cluster. Robots are placed one at a time, each against the space-time
paths of those placed before it:

* robots under way that keep what they do come first, with their current law and delay;
* then the others, longest solo trip first (they decide the makespan) -- except that a
  robot whose every way passes another's goal comes before it (``Fleet.blocks``: it must
  pass before that one parks);
* each takes the option -- a law it may use and a start delay from ``delays`` -- that
  arrives first (delay + solo time) among those whose solo path, shifted by the delay
  (standing at its start meanwhile), stays at least ``reach`` [m] from every placed path
  at the same sample time (one sample either side) and from every standing robot;
* a robot with no such option takes the one whose first conflict comes latest, leaving
  out the start delays that only postpone it: a delay that moves the conflict by exactly
  itself (a standing robot, one parked, a path that stays in the way) buys nothing, and
  would otherwise always win (the longest delay there is).

Paths are the scene's solo predictions (each robot alone, static obstacles, no peers),
sampled every ``period`` [s]; a robot that arrived stays at its goal. The repulsion of
Eq. (27) bends real paths, which is why the result is only a seed: rollouts verify it and
repair what is left.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet.core.planner.gates import blocked_first
from fleet.core.planner.scene import UNDER_WAY, Candidate, Fleet
from fleet.core.types import FloatArray, IntArray


def _options(solo: FloatArray, laws: IntArray, shifts: IntArray, length: int) -> FloatArray:
    """Paths (O, L, 2) of one robot: option o is its solo path with law ``laws[o]`` (solo:
    (T, 2 laws, 2)) delayed by ``shifts[o]`` samples -- standing at its start meanwhile, at
    its end once done."""
    t = solo.shape[0]
    idx = np.clip(np.arange(length)[None, :] - shifts[:, None], 0, t - 1)
    out: FloatArray = solo[idx, laws[:, None]]
    return out


def _first_conflicts(
    paths: FloatArray, placed: FloatArray, standing: FloatArray, reach: float, stand_reach: float
) -> IntArray:
    """Per option path (O, L, 2): the first sample where it comes within ``reach`` of a
    placed path (P, L, 2) at about the same time (one sample either side), or within
    ``stand_reach`` of a standing robot; L where it never does."""
    n_opt, length = paths.shape[0], paths.shape[1]
    hit = np.zeros((n_opt, length), dtype=bool)
    if placed.shape[0]:  # only placed paths whose box comes near these ones'
        lo = paths.min(axis=(0, 1)) - reach
        hi = paths.max(axis=(0, 1)) + reach
        placed = placed[((placed.max(axis=1) >= lo) & (placed.min(axis=1) <= hi)).all(axis=1)]
    r2 = reach * reach
    for off in (-1, 0, 1) if placed.shape[0] else ():
        idx = np.clip(np.arange(length) + off, 0, length - 1)
        d = placed[None, :, idx] - paths[:, None]  # (O, P, L, 2)
        hit |= ((d * d).sum(axis=3) < r2).any(axis=1)
    if standing.shape[0]:
        d = paths[:, :, None, :] - standing[None, None]
        hit |= ((d * d).sum(axis=3) < stand_reach * stand_reach).any(axis=2)
    first: IntArray = np.where(hit.any(axis=1), np.argmax(hit, axis=1), length)
    return first


def _latest_real_conflict(first: IntArray, laws: IntArray, shifts: IntArray) -> int:
    """The option (index) whose first conflict (sample) comes latest among those whose
    delay (``shifts``, samples) does more than postpone the conflict of the same law's
    shortest delay; ties to the earliest index (the soonest arrival)."""
    useful = np.ones(first.size, dtype=bool)
    driven = first - shifts  # samples each option drives before its first conflict
    for law in np.unique(laws):
        same = laws == law
        shortest = shifts[same].min()
        ref = driven[same & (shifts == shortest)][0]
        useful &= ~(same & (shifts > shortest) & (driven == ref))
    options = np.flatnonzero(useful)
    return int(options[np.argmax(first[options])])


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
    # every robot gets a way to go (the search holds if it must), but a robot waiting for a
    # zone stands where it is
    keep.hold[:] = fleet.forced(idx)
    times = fleet.solo_times
    period = float(times[1] - times[0]) if times.size > 1 else 1.0
    waits = np.array([0.0, *delays])
    shifts = np.round(waits / period).astype(np.int64)
    length = times.size + int(shifts.max())
    solo = fleet.solo_time[idx]
    fastest = np.min(np.where(m.allowed[idx], solo, np.inf), axis=1)
    kept = (m.kind[idx] == UNDER_WAY) & ~m.keep_hold[idx]
    order = blocked_first(
        sorted(range(idx.size), key=lambda p: (not kept[p], -fastest[p], p)),
        fleet.blocks[np.ix_(idx, idx)],
    )
    fixed = fleet.standing_xy[np.asarray(standing, dtype=np.int64)].reshape(-1, 2)
    paths = np.zeros((idx.size, length, 2))
    placed: list[int] = []
    for p in order:
        i = int(idx[p])
        if keep.hold[p]:
            paths[p] = fleet.solo_xy[0, i, keep.law[p]]
            placed.append(p)
            continue
        if kept[p]:
            laws = np.array([keep.law[p]])
            wait = np.array([keep.delay[p]])
        else:
            laws = np.repeat([law for law in (0, 1) if m.allowed[i, law]], waits.size)
            wait = np.tile(waits, laws.size // waits.size)
            order_opt = np.argsort(wait + solo[p, laws], kind="stable")  # soonest arrival first
            laws, wait = laws[order_opt], wait[order_opt]
        shift = np.round(wait / period).astype(np.int64)
        options = _options(fleet.solo_xy[:, i], laws, shift, length)
        first = _first_conflicts(options, paths[placed], fixed, reach, stand_reach)
        clear = np.flatnonzero(first == length)
        pick = int(clear[0]) if clear.size else _latest_real_conflict(first, laws, shift)
        keep.law[p], keep.delay[p] = int(laws[pick]), float(wait[pick])
        paths[p] = options[pick]
        placed.append(p)
    return keep, paths


__all__ = ["reservation"]
