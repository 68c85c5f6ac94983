"""A route graph over the free space of a site (pure): where a robot can drive around walls.

World frame, metres, headings in radians counter-clockwise from east. A robot is a disc; its
*centre* must stay ``clearance_m`` from every obstacle's solid body (a capsule: the segment
of :class:`~fleet.core.wire.Obstacle` with radius ``body_radius``). The forbidden region is
the union of those capsules grown by ``clearance_m``.

:class:`Roadmap` is a visibility graph (shapely for the geometry, networkx for the graph):

- nodes: the convex corners of the outline of the capsules grown a little further
  (``clearance_m`` + a margin of ``max(0.05, 5 % of clearance_m)``), with as few chords per
  arc as keep each chord outside the forbidden region (a post of 0.5 m: 8 nodes), simplified.
  A gap narrower than twice the margin (beyond the clearance) has no nodes of its own;
- edges: node pairs whose straight segment keeps the clearance from every body (checked
  exactly against the capsules with an STRtree), weighted by their length [m]. Only edges
  tangent to the outline at both nodes are kept (the reduced visibility graph: a shortest
  path never uses the others), which prunes most pairs before any geometry is checked.
  An edge that hugs an island standing alone -- a post, a short wall segment touching no
  other, or a small group of bodies no robot passes between (their rings overlap), with no
  other obstacle within two robots' passing room of it; the edge's middle within its grown
  ring; :func:`_islands` -- costs ``1 + ROUNDABOUT_PRICE`` times its length when driven
  clockwise round its centre: robots whose ways round it are about as long either side all
  go round it counter-clockwise, a roundabout, instead of meeting head-on beside it; a much
  shorter way clockwise is still taken. The fleet routes on a roadmap whose
  lone islands are grown to their Eq. (27) zones where that gives a way
  (:func:`roundabouts`, :func:`fleet.core.planner.lanes.route_graph`).

Robots start and park close to obstacles, so the segments leaving the start and reaching the
goal (or the pre-bay point) need, from every body, only the clearance that end point itself
has: ``min(clearance_m, its distance to the nearest body - 0.01)``, never below 0 (a segment
joining two such points: the smaller). Every other segment keeps ``clearance_m``.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np
import numpy.typing as npt
import shapely

from fleet.core.types import BoolArray, FloatArray, IntArray
from fleet.core.wire import Obstacle

Point = tuple[float, float]
GeometryArray = npt.NDArray[np.object_]

MAX_NODES = 3000  # beyond this the graph's O(n^2) pairs take seconds to build
END_SLACK_M = 0.01  # an end point's reduced clearance stays this far inside what it has
_START, _TARGET = -1, -2  # placeholder nodes of every query (see Roadmap.graph)
_TANGENT_TOL = 1e-12
_POINT_M = 1e-9  # a segment shorter than this [m] is a point
_SAG = 0.85  # an arc's chords cut at most this share of the margin into it
_SIMPLIFY_M = 1e-4  # the grown outline's simplification tolerance [m]
_PAIRS_PER_BLOCK = 1 << 20  # node pairs screened at once (memory bound)
#: Extra share of an edge's length when it is driven clockwise round the island it hugs.
ROUNDABOUT_PRICE = 0.5
#: The same on a one-way roadmap (:func:`roadmap_of` with ``one_way``): clockwise only
#: where that way is four times shorter.
ONE_WAY_PRICE = 3.0
_NOT_HUGGING = -3  # ``ccw_from`` of an edge that hugs no post


def _margin(clearance_m: float) -> float:
    """How much further out than the clearance the nodes lie [m]."""
    return max(0.05, 0.05 * clearance_m)


def obstacle_geometries(obstacles: Sequence[Obstacle]) -> GeometryArray:
    """Each obstacle's segment (a point for a post) as a shapely geometry."""
    out = np.empty(len(obstacles), dtype=object)
    for k, o in enumerate(obstacles):
        end = o.far_end
        out[k] = (
            shapely.Point(o.x, o.y)
            if math.dist(end, (o.x, o.y)) < _POINT_M
            else shapely.LineString([(o.x, o.y), end])
        )
    return out


def _segments(a: FloatArray, b: FloatArray) -> GeometryArray:
    """Line strings from rows of ``a`` (M, 2) to rows of ``b`` (M, 2); a point where they
    nearly coincide (GEOS divides by a line's length)."""
    out = np.asarray(shapely.linestrings(np.stack([a, b], axis=1)), dtype=object)
    same = np.hypot(*(b - a).T) < _POINT_M
    if same.any():
        out[same] = shapely.points(a[same])
    return out


@dataclass(frozen=True, eq=False)
class Roadmap:
    """The visibility graph of one obstacle set and clearance; build with :meth:`build`.

    ``nodes`` (N, 2) [m] are the graph's node positions (node ``i`` of ``graph``);
    ``graph`` also holds two placeholder nodes joined to every node and to each other,
    the start and the target of a query: :meth:`route` weighs their edges per query (and
    hides the rest), so the graph is never modified after :meth:`build`.
    ``forbidden`` is the region no robot centre may enter (for drawing).
    """

    obstacles: tuple[Obstacle, ...]
    clearance_m: float
    #: extra share of a segment's length clockwise round an island it hugs
    clockwise_price: float
    nodes: FloatArray
    graph: Any = field(repr=False)  # networkx.Graph (no stubs)
    forbidden: Any = field(repr=False)  # shapely geometry (no stubs)
    _bodies: FloatArray = field(repr=False)
    _shapes: GeometryArray = field(repr=False)
    _tree: Any = field(repr=False)  # shapely.STRtree over _shapes, or None
    _before: FloatArray = field(repr=False)  # each node's neighbours on its outline ring
    _after: FloatArray = field(repr=False)
    #: the islands standing alone (:func:`_islands`), each the indices into ``obstacles``
    #: of its bodies: one, or a group no robot passes between
    island_groups: tuple[IntArray, ...] = field(repr=False)
    _senses: _Senses = field(repr=False)

    @property
    def islands(self) -> IntArray:
        """The obstacles standing alone as islands of one body (indices into
        ``obstacles``): the posts and short walls :func:`roundabouts` grows."""
        return np.array([g[0] for g in self.island_groups if len(g) == 1], dtype=np.int64)

    @classmethod
    def build(
        cls, obstacles: Sequence[Obstacle], clearance_m: float, *, max_nodes: int = MAX_NODES,
        clockwise_price: float = ROUNDABOUT_PRICE,
    ) -> Roadmap:  # fmt: skip
        """The roadmap for ``obstacles`` and a centre clearance ``clearance_m`` [m] (robot
        radius + safety margin + slack), a way clockwise round an island costing
        ``1 + clockwise_price`` times its length. Raises ValueError for a negative or
        non-finite clearance or price, or when the graph would have more than ``max_nodes``
        nodes."""
        if not (math.isfinite(clearance_m) and clearance_m >= 0.0):
            raise ValueError(f"clearance_m must be finite and >= 0, not {clearance_m}")
        if not (math.isfinite(clockwise_price) and clockwise_price >= 0.0):
            raise ValueError(f"clockwise_price must be finite and >= 0, not {clockwise_price}")
        obstacles = tuple(obstacles)
        shapes = obstacle_geometries(obstacles)
        bodies = np.array([o.body_radius for o in obstacles], dtype=np.float64)
        tree = shapely.STRtree(shapes) if len(obstacles) else None
        forbidden = shapely.union_all(shapely.buffer(shapes, bodies + clearance_m))
        empty = np.empty((0, 2), dtype=np.float64)
        ring, room = _rings(bodies, clearance_m)
        islands = _islands(shapes, tree, ring, room)
        senses = _Senses.of(shapes, islands, ring)
        probe = cls(
            obstacles, clearance_m, clockwise_price, empty, None, forbidden, bodies, shapes,
            tree, empty, empty, islands, senses,
        )  # fmt: skip

        xy, before, after = _outline_corners(shapes, bodies + clearance_m, _margin(clearance_m))
        keep = ~probe._blocked(shapely.points(xy), bodies + clearance_m)
        xy, before, after = xy[keep], before[keep], after[keep]
        if len(xy) > max_nodes:
            raise ValueError(
                f"the roadmap would have {len(xy)} nodes, more than {max_nodes}: too many "
                f"or too large obstacles ({len(obstacles)}) for a route graph"
            )
        for array in (xy, before, after):
            array.setflags(write=False)

        graph = nx.Graph()
        graph.add_nodes_from(range(len(xy)))
        i, j = _tangent_pairs(xy, before, after)
        if len(i):
            open_ = ~probe._blocked(_segments(xy[i], xy[j]), bodies + clearance_m)
            i, j = i[open_], j[open_]
            lengths = np.hypot(*(xy[j] - xy[i]).T)
            sense = senses.of_segments(xy[i], xy[j])
            ccw_from = np.where(sense == 0, _NOT_HUGGING, np.where(sense > 0, i, j))
            graph.add_edges_from(
                (a, b, {"length": length, "ccw_from": start})
                for a, b, length, start in zip(
                    i.tolist(), j.tolist(), lengths.tolist(), ccw_from.tolist(), strict=True
                )
            )
        for end in (_START, _TARGET):
            graph.add_edges_from((end, n) for n in range(len(xy)))
        graph.add_edge(_START, _TARGET)
        return cls(
            obstacles, clearance_m, clockwise_price, xy, graph, forbidden, bodies, shapes,
            tree, before, after, islands, senses,
        )  # fmt: skip

    def free(self, a: Point, b: Point) -> bool:
        """Whether the segment from ``a`` to ``b`` [m] keeps ``clearance_m`` from every
        body (strictly farther)."""
        return not self._segment_blocked(a, b, self._bodies + self.clearance_m)

    def clear(self, a: Point, b: Point, clearance_m: float) -> bool:
        """Whether the segment from ``a`` to ``b`` [m] keeps ``clearance_m`` [m] (e.g. a
        robot's radius: its body's straight way) from every body."""
        return not self._segment_blocked(a, b, self._bodies + clearance_m)

    def sees(self, point: Point, targets: FloatArray) -> BoolArray:
        """(N,) which of ``targets`` (N, 2) [m] the straight way from ``point`` reaches
        keeping, from every body, the clearance ``point`` itself has
        (:meth:`end_clearance`): a robot standing there may drive to them."""
        targets = np.asarray(targets, dtype=np.float64).reshape(-1, 2)
        if len(targets) == 0:
            return np.zeros(0, dtype=bool)
        starts = np.broadcast_to(np.array(point, dtype=np.float64), targets.shape)
        return ~self._blocked(_segments(starts, targets), self._end_need(point))

    def end_clearance(self, point: Point) -> float:
        """The clearance [m] a segment ending at ``point`` [m] must keep from every body:
        ``min(clearance_m, point's distance to the nearest body - 0.01)``, never below 0."""
        own = self._surface_distance(point)
        return max(0.0, min(self.clearance_m, own - END_SLACK_M))

    def route(
        self, start: Point, goal: tuple[float, float, float], approach_m: float
    ) -> tuple[Point, ...] | None:
        """Via-points [m] for a robot at ``start`` (x, y) to park at ``goal`` (x, y,
        heading [rad]); the last leg is the posture controller's, from the pre-bay point
        ``goal - approach_m * (cos h, sin h)`` [m].

        ``()``: the straight segment start -> goal is free. Otherwise the shortest path
        start -> ... -> pre-bay point, without the start, with the pre-bay point last; when
        the pre-bay point is not free (or not reachable, or its leg to the goal is not free),
        the shortest path to the goal without the start and the goal. None: no path.
        """
        values = (*start, *goal, approach_m)
        if not all(math.isfinite(v) for v in values) or approach_m < 0.0:
            raise ValueError(f"route needs finite points and approach_m >= 0, not {values}")
        s = (float(start[0]), float(start[1]))
        g = (float(goal[0]), float(goal[1]))
        need_s, need_g = self._end_need(s), self._end_need(g)
        if not self._segment_blocked(s, g, np.minimum(need_s, need_g)):
            return ()
        if approach_m > 0.0:
            p = pre_bay_point(goal, approach_m)
            need_p = self._end_need(p)
            inside = self.end_clearance(p) <= 0.0  # within END_SLACK_M of a body, or in one
            if not inside and not self._segment_blocked(p, g, np.minimum(need_p, need_g)):
                via = self._shortest(s, need_s, p, need_p)
                if via is not None:
                    return (*via, p)
        return self._shortest(s, need_s, g, need_g)

    def keeps(
        self, start: Point, goal: tuple[float, float, float], approach_m: float,
        way: tuple[Point, ...],
    ) -> bool:  # fmt: skip
        """Whether ``way`` (via-points [m], as :meth:`route` returns them, e.g. from another
        roadmap) from ``start`` to ``goal`` keeps the clearances this roadmap's own routes
        keep: ``clearance_m`` from every body, less only at the start, the pre-bay point
        (when ``way`` ends there) and the goal, each its own (:meth:`end_clearance`)."""
        s, g = (float(start[0]), float(start[1])), (float(goal[0]), float(goal[1]))
        p = pre_bay_point(goal, approach_m)
        to_p = bool(way) and approach_m > 0.0 and math.dist(way[-1], p) < 1e-9
        ends = {s, g, p} if to_p else {s, g}
        full = self._bodies + self.clearance_m

        def need(point: Point) -> FloatArray:
            return self._end_need(point) if point in ends else full

        points = [s, *((float(x), float(y)) for x, y in way), g]
        return not any(
            self._segment_blocked(a, b, np.minimum(need(a), need(b)))
            for a, b in itertools.pairwise(points)
        )

    # -- internals -------------------------------------------------------------------------

    def _blocked(self, geometries: GeometryArray, need: FloatArray) -> BoolArray:
        """Which ``geometries`` come within ``need[k]`` [m] (or closer) of obstacle ``k``'s
        segment, for any ``k``."""
        out = np.zeros(len(geometries), dtype=bool)
        if self._tree is None or len(geometries) == 0:
            return out
        reach = float(need.max())
        gi, ok = self._tree.query(geometries, predicate="dwithin", distance=reach)
        if not np.all(need == reach):  # the query used the largest need: check each pair
            near = shapely.distance(geometries[gi], self._shapes[ok]) <= need[ok]
            gi = gi[near]
        out[gi] = True
        return out

    def _segment_blocked(self, a: Point, b: Point, need: FloatArray) -> bool:
        line = _segments(np.array([a], dtype=np.float64), np.array([b], dtype=np.float64))
        return bool(self._blocked(line, need)[0])

    def _surface_distance(self, point: Point) -> float:
        """[m] from ``point`` to the nearest body's surface (inf without obstacles)."""
        if self._tree is None:
            return math.inf
        return float(np.min(shapely.distance(shapely.Point(point), self._shapes) - self._bodies))

    def _end_need(self, point: Point) -> FloatArray:
        """How far [m] from each obstacle's segment a segment ending at ``point`` must
        stay: body + the point's own clearance (:meth:`end_clearance`)."""
        return np.asarray(self._bodies + self.end_clearance(point), dtype=np.float64)

    def _visible(self, point: Point, need: FloatArray) -> tuple[list[int], list[float]]:
        """The nodes whose segment from ``point`` is free under ``need`` and tangent to
        the outline at the node (from outside the outline a shortest path uses no other),
        and the lengths [m]. From a ``point`` inside the outline -- within the clearance
        plus the nodes' margin of a body, e.g. a robot in a corridor a little off its
        centre line -- every node: the tangent ones may all lie behind it (it was routed
        back out of the mouth it came in by), and an island's sense may make another
        cheaper."""
        origin = np.array(point, dtype=np.float64)
        d = self.nodes - origin
        inside = self._surface_distance(point) < self.clearance_m + _margin(self.clearance_m)
        tangent = _one_side(d, self.nodes, self._before, self._after)
        ids = np.arange(len(d)) if inside else np.flatnonzero(tangent)
        if len(ids) == 0:
            return [], []
        starts = np.broadcast_to(origin, (len(ids), 2))
        ids = ids[~self._blocked(_segments(starts, self.nodes[ids]), need)]
        return ids.tolist(), np.hypot(*d[ids].T).tolist()

    def _price(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """(n,) the factor on each segment ``a`` -> ``b`` ((n, 2) each) [m]'s length, as on
        a graph edge: ``1 + clockwise_price`` clockwise round an island it hugs, else 1."""
        return np.where(self._senses.of_segments(a, b) < 0, 1.0 + self.clockwise_price, 1.0)

    def _legs(
        self, point: Point, ids: list[int], lengths: list[float], *, leaving: bool
    ) -> dict[int, float]:
        """The priced lengths (:meth:`_price`) of the legs between ``point`` and the nodes
        ``ids`` of ``lengths`` [m], from ``point`` when ``leaving``, else to it."""
        if not ids:
            return {}
        here = np.broadcast_to(np.array(point, dtype=np.float64), (len(ids), 2))
        there = self.nodes[ids]
        price = self._price(here, there) if leaving else self._price(there, here)
        return dict(zip(ids, (np.asarray(lengths) * price).tolist(), strict=True))

    def _shortest(
        self, s: Point, need_s: FloatArray, t: Point, need_t: FloatArray
    ) -> tuple[Point, ...] | None:
        """The nodes [m] of the shortest path from ``s`` to ``t`` (both excluded), or None.
        Every segment clockwise round an island it hugs costs ``1 + clockwise_price`` times
        its length, the query's own first and last legs too."""
        from_s = self._legs(s, *self._visible(s, need_s), leaving=True)
        to_t = self._legs(t, *self._visible(t, need_t), leaving=False)
        direct = None
        if not self._segment_blocked(s, t, np.minimum(need_s, need_t)):
            ends = np.array([s], dtype=np.float64), np.array([t], dtype=np.float64)
            direct = math.dist(s, t) * float(self._price(*ends)[0])

        def weight(u: int, v: int, data: dict[str, float]) -> float | None:
            if u >= 0 and v >= 0:  # u -> v: clockwise round the post it hugs costs more
                hugging = data["ccw_from"] != _NOT_HUGGING and data["ccw_from"] != u
                return data["length"] * (1.0 + self.clockwise_price) if hugging else data["length"]
            if u > v:
                u, v = v, u
            if u == _TARGET:
                return direct if v == _START else to_t.get(v)
            return from_s.get(v)  # u == _START, v a node

        if direct is None and (not from_s or not to_t):
            return None
        try:
            _, path = nx.bidirectional_dijkstra(self.graph, _START, _TARGET, weight=weight)
        except nx.NetworkXNoPath:
            return None
        return tuple((float(self.nodes[n, 0]), float(self.nodes[n, 1])) for n in path[1:-1])


def _snap(xy: FloatArray) -> FloatArray:
    """Coordinates [m] to the nearest multiple of ``_POINT_M``."""
    snapped: FloatArray = np.round(xy / _POINT_M) * _POINT_M
    return snapped


@dataclass(frozen=True)
class _Senses:
    """Which way a segment runs round the island it hugs (:func:`_islands`): the island's
    convex hull nearest the segment's middle, that middle within the island's largest ring
    [m] of it; counter-clockwise or clockwise round the hull's centre. A wall of posts or a
    gap between two posts (driven through either way) has no sense."""

    hulls: GeometryArray
    centres: FloatArray  # (p, 2) [m]
    rings: FloatArray  # (p,) [m]
    tree: Any  # shapely.STRtree over hulls, or None

    @classmethod
    def of(cls, shapes: GeometryArray, islands: tuple[IntArray, ...], ring: FloatArray) -> _Senses:
        # On a nanometre grid first: bodies a rounding error thick make a sliver hull, whose
        # distances divide by zero in GEOS; snapped, it is the line it is.
        hulls = np.array(
            [
                shapely.convex_hull(shapely.transform(shapely.union_all(shapes[g]), _snap))
                for g in islands
            ],
            dtype=object,
        )
        # A hull of bodies (nearly) on one point is that point (no zero-length segment).
        dot = (shapely.get_dimensions(hulls) == 1) & (shapely.length(hulls) < _POINT_M)
        hulls[dot] = shapely.centroid(hulls[dot])
        centres = shapely.get_coordinates(shapely.centroid(hulls)).reshape(-1, 2)
        rings = np.array([ring[g].max() for g in islands], dtype=np.float64)
        return cls(hulls, centres, rings, shapely.STRtree(hulls) if len(hulls) else None)

    def of_segments(self, a: FloatArray, b: FloatArray) -> IntArray:
        """(n,) for the segments ``a`` -> ``b`` ((n, 2) each) [m]: +1 counter-clockwise
        round the island each hugs, -1 clockwise, 0 hugging none."""
        out = np.zeros(len(a), dtype=np.int64)
        if self.tree is None or len(a) == 0:
            return out
        middle = shapely.points(0.5 * (a + b))
        # The nearest island of each middle (a tree: O(n log p), not n x p).
        nearest = self.tree.nearest(middle)
        hugs = shapely.distance(middle, self.hulls[nearest]) <= self.rings[nearest]
        arm, step = a - self.centres[nearest], b - a
        turn = arm[:, 0] * step[:, 1] - arm[:, 1] * step[:, 0]  # > 0: counter-clockwise
        out[hugs] = np.where(turn[hugs] > 0.0, 1, -1)
        return out


def pre_bay_point(goal: tuple[float, float, float], approach_m: float) -> Point:
    """The point [m] ``approach_m`` [m] in front of ``goal`` (x, y, heading [rad]), where a
    route ends and the posture controller's last leg begins."""
    h = float(goal[2])
    return (float(goal[0]) - approach_m * math.cos(h), float(goal[1]) - approach_m * math.sin(h))


def _islands(
    shapes: GeometryArray, tree: Any, ring: FloatArray, room: float
) -> tuple[IntArray, ...]:
    """The islands standing alone among ``shapes`` (which the STRtree ``tree`` holds), each
    as the indices of its bodies: a group of bodies whose ``ring`` [m] overlaps the next one's
    (no robot passes between them; one body alone is a group too), with every other
    obstacle's ring at least ``room`` [m] (two robots passing) from each of its rings, and
    small: its convex hull's perimeter (a segment's: twice its length) no longer than its
    largest ring's circumference (a post; a wall segment whose straight sides are no longer
    than its round ends; two or three posts side by side: robots circle it; along a longer
    one, a divider or a row of posts, they drive by). The segments of one wall touch: they
    are one group."""
    if tree is None or len(shapes) == 0:
        return ()
    # Pairs nearer than their rings and the room: a tree query at the largest such
    # distance, then each pair's own (as `Roadmap._blocked` does).
    reach = 2.0 * float(ring.max()) + room
    pi, ok = tree.query(shapes, predicate="dwithin", distance=reach)
    other = ok != pi  # an obstacle is not near itself
    pi, ok = pi[other], ok[other]
    gap = shapely.distance(shapes[pi], shapes[ok]) - ring[pi] - ring[ok]
    joined = gap < 0.0
    graph = nx.Graph()
    graph.add_nodes_from(range(len(shapes)))
    graph.add_edges_from(zip(pi[joined].tolist(), ok[joined].tolist(), strict=True))
    group_of = np.empty(len(shapes), dtype=np.int64)
    groups = [np.array(sorted(c), dtype=np.int64) for c in nx.connected_components(graph)]
    for k, members in enumerate(groups):
        group_of[members] = k
    crowded = np.zeros(len(groups), dtype=bool)
    outside = (gap < room) & (group_of[pi] != group_of[ok])
    crowded[group_of[pi[outside]]] = True
    out = []
    for k, members in enumerate(groups):
        if crowded[k]:
            continue
        hull = shapely.convex_hull(shapely.union_all(shapes[members]))
        around = shapely.length(hull) / (2.0 if shapely.get_dimensions(hull) == 2 else 1.0)
        if around <= np.pi * float(ring[members].max()):
            members.setflags(write=False)
            out.append(members)
    return tuple(out)


def _rings(bodies: FloatArray, clearance_m: float) -> tuple[FloatArray, float]:
    """The rings [m] round each body a route hugs (its nodes lie within them) and the room
    [m] between two rings that two robots need to pass each other."""
    return bodies + clearance_m + 2.0 * _margin(clearance_m), 4.0 * clearance_m


def roundabouts(obstacles: tuple[Obstacle, ...], clearance_m: float) -> tuple[Obstacle, ...]:
    """``obstacles`` with the body of every island standing alone (:func:`_islands`, of one body, at
    ``clearance_m`` [m]: a post, or a short wall segment touching no other) grown to its Eq. (27)
    influence radius: routed on these, a robot's via-points round it lie ``clearance_m``
    outside its zone, where the paper's -K_avoid/x_OA cannot hold it short of them (the
    paper keeps desired postures out of every zone), and robots circling it keep apart
    (docs/benchmarks.md, eighteenth stop). ``obstacles`` itself when none grows."""
    grow = _growing(obstacles, clearance_m)
    if not grow:
        return obstacles
    out = list(obstacles)
    for k in grow:
        out[k] = obstacles[k].model_copy(update={"body": obstacles[k].radius})
    return tuple(out)


def roundabout_islands(obstacles: tuple[Obstacle, ...], clearance_m: float) -> tuple[Obstacle, ...]:
    """The lone obstacles of ``obstacles`` that :func:`roundabouts` grows (as they are)."""
    return tuple(obstacles[k] for k in _growing(obstacles, clearance_m))


def _growing(obstacles: tuple[Obstacle, ...], clearance_m: float) -> tuple[int, ...]:
    """The lone islands of ``obstacles`` whose influence radius exceeds their body (from
    the roadmap the fleet routes on, :func:`roadmap_of`: computed once per obstacle set)."""
    if not obstacles:
        return ()
    islands = roadmap_of(obstacles, clearance_m).islands.tolist()
    return tuple(k for k in islands if obstacles[k].radius > obstacles[k].body_radius)


def _outline_corners(
    shapes: GeometryArray, reach: FloatArray, margin: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The convex corners (N, 2) [m] of the outline of the capsules ``reach + margin``
    around ``shapes``, with each corner's neighbours on its ring (before, after: N, 2).

    Each capsule's arcs get as few vertices as keep its chords more than
    ``(1 - _SAG) * margin`` outside the capsule ``reach`` (a post of 0.5 m: 8), and the
    union is simplified (collinear and near-duplicate vertices dropped)."""
    empty = np.empty((0, 2), dtype=np.float64)
    if len(shapes) == 0:
        return empty, empty, empty
    grown_by = reach + margin
    # a quarter circle in q chords sags grown_by * (1 - cos(pi / (4 q))); keep that <= _SAG * m
    quarter = np.pi / (4.0 * np.arccos(1.0 - np.minimum(_SAG * margin / grown_by, 1.0)))
    quad_segs = np.maximum(np.ceil(quarter - 1e-9), 2).astype(int)
    parts = [
        shapely.buffer(shapes[quad_segs == q], grown_by[quad_segs == q], quad_segs=int(q))
        for q in np.unique(quad_segs)
    ]
    grown = shapely.union_all(np.concatenate(parts))
    outline = shapely.orient_polygons(  # exteriors counter-clockwise, holes clockwise
        shapely.simplify(grown, _SIMPLIFY_M, preserve_topology=True)
    )
    corners, befores, afters = [], [], []
    for polygon in shapely.get_parts(outline):
        for ring in (polygon.exterior, *polygon.interiors):
            xy = shapely.get_coordinates(ring)[:-1]
            if len(xy) < 3:
                continue
            before, after = np.roll(xy, 1, axis=0), np.roll(xy, -1, axis=0)
            u, w = xy - before, after - xy
            convex = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0] > _TANGENT_TOL  # body on the left
            corners.append(xy[convex])
            befores.append(before[convex])
            afters.append(after[convex])
    if not corners:
        return empty, empty, empty
    return np.concatenate(corners), np.concatenate(befores), np.concatenate(afters)


def _tangent_pairs(
    xy: FloatArray, before: FloatArray, after: FloatArray
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """The node pairs (i < j) whose line is tangent to the outline at both nodes: each
    node's two ring neighbours lie on one side of it (or on it)."""
    n = len(xy)
    block = max(1, _PAIRS_PER_BLOCK // max(n, 1))
    found_i, found_j = [], []
    for first in range(0, n, block):
        rows = np.arange(first, min(n, first + block))
        d = xy[None, :, :] - xy[rows, None, :]  # (B, N, 2), from node i to node j

        ok = _one_side(d, xy[rows, None], before[rows, None], after[rows, None])
        ok &= _one_side(d, xy[None], before[None], after[None])
        ok &= np.arange(n)[None, :] > rows[:, None]
        bi, j = np.nonzero(ok)
        found_i.append(rows[bi])
        found_j.append(j)
    if not found_i:
        none = np.empty(0, dtype=np.intp)
        return none, none
    return np.concatenate(found_i), np.concatenate(found_j)


def _one_side(d: FloatArray, at: FloatArray, nb1: FloatArray, nb2: FloatArray) -> BoolArray:
    """Whether the neighbours ``nb1`` and ``nb2`` of the nodes ``at`` lie on one side of
    (or on) the lines through ``at`` along ``d`` (all broadcast, last axis x, y)."""
    s1 = d[..., 0] * (nb1 - at)[..., 1] - d[..., 1] * (nb1 - at)[..., 0]
    s2 = d[..., 0] * (nb2 - at)[..., 1] - d[..., 1] * (nb2 - at)[..., 0]
    opposite = ((s1 > _TANGENT_TOL) & (s2 < -_TANGENT_TOL)) | (
        (s1 < -_TANGENT_TOL) & (s2 > _TANGENT_TOL)
    )
    return np.asarray(~opposite)


@functools.lru_cache(maxsize=8)
def roadmap_of(
    obstacles: tuple[Obstacle, ...], clearance_m: float, *, one_way: bool = False
) -> Roadmap:
    """:meth:`Roadmap.build`, kept for the last few obstacle sets and clearances (a site's
    obstacles change rarely; the planner and the goal check share it), the way clockwise
    round an island priced ``ROUNDABOUT_PRICE``, or ``ONE_WAY_PRICE`` when ``one_way``.
    Read-only: safe to share between threads."""
    price = ONE_WAY_PRICE if one_way else ROUNDABOUT_PRICE
    return Roadmap.build(obstacles, clearance_m, clockwise_price=price)
