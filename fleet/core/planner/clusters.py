"""Clusters of robots whose predicted paths interact (pure).

Predictions are paths sampled every ``period`` [s] with a mask of the samples where the
robot *moves* (after its start delay, before it arrives; a robot that waits stands at its
start, one that arrived stays at its goal). Two robots have an *encounter* when their
positions come within ``reach`` [m] of each other at samples at most ``window`` apart:

* both moving -- they interact both ways: same cluster (connected components);
* one standing -- only the moving one reacts (a waiting or arrived robot does not move):
  its cluster gets the standing robot as a *phantom*, a standing obstacle at that start or
  goal for its whole rollout (conservative: it is there only part of the time), and the
  two robots need not be searched together.

Standing robots (no task to decide) near a cluster's paths join it as standing rows (one
may join several: it couples nobody). Robots of different clusters then never come within
``reach`` of each other while both move, so each cluster can be searched alone.

Before a plan is searched, the prediction is the prioritised seed on solo paths (reach =
peer radius + a margin); after, it is the chosen plans' rollouts (reach = the peer radius,
where Eq. (27) starts acting): the planner merges clusters that now interact, and adds
phantoms a cluster did not know, and searches those again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.types import BoolArray, FloatArray

#: Row pairs checked per vectorised chunk (bounds memory: pairs x samples x 2 floats).
_CHUNK = 256
#: Phantoms closer than this [m] to one a cluster has are the same.
SAME_PLACE_M = 0.05

Phantom = tuple[float, float, int]  # (x [m], y [m], mover index of the robot standing there)


@dataclass(frozen=True)
class Cluster:
    """Movers searched together, the standing robots near them, and phantoms: movers of
    other clusters standing (waiting or arrived) where this cluster passes."""

    movers: tuple[int, ...]
    standing: tuple[int, ...]
    phantoms: tuple[Phantom, ...] = ()

    def knows(self, p: Phantom) -> bool:
        return any(
            q[2] == p[2] and abs(q[0] - p[0]) < SAME_PLACE_M and abs(q[1] - p[1]) < SAME_PLACE_M
            for q in self.phantoms
        )


@dataclass(frozen=True)
class Encounters:
    """Both-moving pairs of movers, and phantoms each mover needs (one-way encounters)."""

    pairs: list[tuple[int, int]]
    phantoms: dict[int, set[Phantom]]


def _boxes(paths: FloatArray, reach: float) -> FloatArray:
    """(R, 4) bounding boxes (x0, y0, x1, y1) of each path, grown by ``reach`` / 2."""
    lo = paths.min(axis=1) - reach / 2
    hi = paths.max(axis=1) + reach / 2
    return np.concatenate([lo, hi], axis=1)


def _overlapping(a: FloatArray, b: FloatArray) -> BoolArray:
    return (
        (a[:, None, 0] <= b[None, :, 2])
        & (b[None, :, 0] <= a[:, None, 2])
        & (a[:, None, 1] <= b[None, :, 3])
        & (b[None, :, 1] <= a[:, None, 3])
    )


def _phase(moving: BoolArray) -> tuple[FloatArray, FloatArray]:
    """Per path (R,): first and last moving sample index (T, -1 for a path that never moves)."""
    t = moving.shape[1]
    any_move = moving.any(axis=1)
    first = np.where(any_move, np.argmax(moving, axis=1), t).astype(np.float64)
    last = np.where(any_move, t - 1 - np.argmax(moving[:, ::-1], axis=1), -1).astype(np.float64)
    return first, last


def encounters(
    paths: FloatArray,
    moving: BoolArray,
    owner: Sequence[int],
    reach: float,
    window: int,
) -> Encounters:
    """Encounters of paths (R, T, 2) with moving masks (R, T), ``owner[r]`` naming the
    mover of path r (several paths may share a mover: one per law it may use)."""
    own = np.asarray(owner, dtype=np.int64)
    found: set[tuple[int, int]] = set()
    phantoms: dict[int, set[Phantom]] = {}
    if paths.shape[0] < 2:
        return Encounters([], phantoms)
    t = paths.shape[1]
    first, last = _phase(moving)
    boxes = _boxes(paths, reach)
    cand = _overlapping(boxes, boxes) & (own[:, None] < own[None, :])
    a_all, b_all = np.nonzero(cand)
    r2 = reach * reach
    steps = np.arange(t)
    for s in range(0, a_all.size, _CHUNK):
        a, b = a_all[s : s + _CHUNK], b_all[s : s + _CHUNK]
        pa, pb, ma, mb = paths[a], paths[b], moving[a], moving[b]
        both = np.zeros(a.size, dtype=bool)
        need = {key: np.zeros(a.size, dtype=bool) for key in ("a<b0", "a<b1", "b<a0", "b<a1")}
        for off in range(-window, window + 1):
            idx = np.clip(steps + off, 0, t - 1)
            d = pa - pb[:, idx]
            hit = (d * d).sum(axis=2) < r2
            mb_off = mb[:, idx]
            both |= (hit & ma & mb_off).any(axis=1)
            a_only, b_only = hit & ma & ~mb_off, hit & ~ma & mb_off
            need["a<b0"] |= (a_only & (idx[None, :] < first[b, None])).any(axis=1)
            need["a<b1"] |= (a_only & (idx[None, :] > last[b, None]) & (last[b, None] >= 0)).any(
                axis=1
            )
            need["b<a0"] |= (b_only & (steps[None, :] < first[a, None])).any(axis=1)
            need["b<a1"] |= (b_only & (steps[None, :] > last[a, None]) & (last[a, None] >= 0)).any(
                axis=1
            )
        found.update((int(own[i]), int(own[j])) for i, j in zip(a[both], b[both], strict=True))
        for key, mask in need.items():
            for p in np.flatnonzero(mask):
                i, j = (a[p], b[p]) if key[0] == "a" else (b[p], a[p])
                xy = paths[j, 0] if key[-1] == "0" else paths[j, -1]
                phantoms.setdefault(int(own[i]), set()).add(
                    (round(float(xy[0]), 3), round(float(xy[1]), 3), int(own[j]))
                )
    return Encounters(sorted(found), phantoms)


def near_standing(
    paths: FloatArray, owner: Sequence[int], standing: FloatArray, reach: float
) -> list[tuple[int, int]]:
    """(owner, standing index) pairs: a path passes within ``reach`` of a standing robot."""
    own = np.asarray(owner, dtype=np.int64)
    if paths.shape[0] == 0 or standing.shape[0] == 0:
        return []
    boxes = _boxes(paths, reach)
    pts = np.concatenate([standing - reach / 2, standing + reach / 2], axis=1)
    a_idx, s_idx = np.nonzero(_overlapping(boxes, pts))
    found: set[tuple[int, int]] = set()
    r2 = reach * reach
    for s in range(0, a_idx.size, _CHUNK):
        a, j = a_idx[s : s + _CHUNK], s_idx[s : s + _CHUNK]
        d = paths[a] - standing[j][:, None, :]
        hit = ((d * d).sum(axis=2) < r2).any(axis=1)
        found.update((int(own[i]), int(k)) for i, k in zip(a[hit], j[hit], strict=True))
    return sorted(found)


def components(n: int, pairs: Sequence[tuple[int, int]]) -> list[list[int]]:
    """Connected components of ``n`` nodes under ``pairs``, each sorted, ordered by first."""
    # scipy on first use: the fleet service plans with it, a robot (``robot`` extra) never.
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if n == 0:
        return []
    rows = np.array([p[0] for p in pairs], dtype=np.int64)
    cols = np.array([p[1] for p in pairs], dtype=np.int64)
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    groups: dict[int, list[int]] = {}
    for i, label in enumerate(labels):
        groups.setdefault(int(label), []).append(i)
    return sorted(groups.values(), key=lambda g: g[0])


def clusters(
    paths: FloatArray,
    moving: BoolArray,
    movers: int,
    standing: FloatArray,
    reach: float,
    window: int,
) -> list[Cluster]:
    """Clusters of ``movers`` robots from their paths (movers, T, 2) and moving masks."""
    owner = list(range(movers))
    found = encounters(paths, moving, owner, reach, window)
    near: dict[int, set[int]] = {}
    for i, s in near_standing(paths, owner, standing, reach):
        near.setdefault(i, set()).add(s)
    out = []
    for group in components(movers, found.pairs):
        members = set(group)
        stand = sorted(set().union(*(near.get(i, set()) for i in group)))
        ghosts = {p for i in group for p in found.phantoms.get(i, set()) if p[2] not in members}
        out.append(Cluster(tuple(group), tuple(stand), tuple(sorted(ghosts))))
    return out


__all__ = [
    "SAME_PLACE_M",
    "Cluster",
    "Encounters",
    "Phantom",
    "clusters",
    "components",
    "encounters",
    "near_standing",
]
