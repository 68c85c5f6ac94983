"""Clusters of robots whose predicted paths interact (pure).

Two moving robots *interact* when their predicted positions come within ``reach`` [m] of
each other at times at most ``slack`` [s] apart (positions sampled every ``period``; a
robot that arrived stays at its goal). A standing robot interacts with a moving one when
the moving one passes within ``reach`` of it at any time. Clusters are the connected
components of moving robots under "interacts"; each cluster also lists the standing
robots its movers pass near (a standing robot may belong to several: it does not move, so
it couples nobody). Robots of different clusters never come within ``reach`` of each
other in the prediction, so each cluster can be searched alone.

Before a plan is searched, the prediction is every robot alone with each law it may use
(reach = peer radius + separation + margin); after, it is the chosen plan's rollout
(reach = the peer radius: where Eq. (27) starts acting). The planner merges clusters that
the second check finds interacting and searches them again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from fleet.core.types import BoolArray, FloatArray

#: Row pairs checked per vectorised chunk (bounds memory: pairs x samples x 2 floats).
_CHUNK = 256


@dataclass(frozen=True)
class Cluster:
    """Indices of movers (searched together) and of the standing robots near them."""

    movers: tuple[int, ...]
    standing: tuple[int, ...]


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


def _close_in_time(a: FloatArray, b: FloatArray, reach: float, window: int) -> BoolArray:
    """(P,) whether paths ``a[p]`` and ``b[p]`` (P, T, 2) come within ``reach`` at sample
    indices at most ``window`` apart."""
    t = a.shape[1]
    hit = np.zeros(a.shape[0], dtype=bool)
    r2 = reach * reach
    for off in range(-window, window + 1):
        idx = np.clip(np.arange(t) + off, 0, t - 1)
        d = a - b[:, idx]
        hit |= ((d * d).sum(axis=2) < r2).any(axis=1)
    return hit


def interacting_pairs(
    paths: FloatArray, owner: Sequence[int], reach: float, window: int
) -> list[tuple[int, int]]:
    """Owner pairs (i < j) of paths (R, T, 2) that interact (see the module docstring)."""
    own = np.asarray(owner, dtype=np.int64)
    if paths.shape[0] < 2:
        return []
    boxes = _boxes(paths, reach)
    cand = _overlapping(boxes, boxes) & (own[:, None] < own[None, :])
    a_idx, b_idx = np.nonzero(cand)
    found: set[tuple[int, int]] = set()
    for s in range(0, a_idx.size, _CHUNK):
        a, b = a_idx[s : s + _CHUNK], b_idx[s : s + _CHUNK]
        hit = _close_in_time(paths[a], paths[b], reach, window)
        found.update((int(own[i]), int(own[j])) for i, j in zip(a[hit], b[hit], strict=True))
    return sorted(found)


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
    owner: Sequence[int],
    movers: int,
    standing: FloatArray,
    reach: float,
    window: int,
) -> list[Cluster]:
    """Clusters of ``movers`` robots from their candidate paths (R, T, 2), ``owner[r]``
    naming the robot of path r (several paths per robot: one per law it may use)."""
    pairs = interacting_pairs(paths, owner, reach, window)
    near: dict[int, set[int]] = {}
    for i, s in near_standing(paths, owner, standing, reach):
        near.setdefault(i, set()).add(s)
    out = []
    for group in components(movers, pairs):
        stand = sorted(set().union(*(near.get(i, set()) for i in group)))
        out.append(Cluster(tuple(group), tuple(stand)))
    return out


__all__ = ["Cluster", "clusters", "components", "interacting_pairs", "near_standing"]
