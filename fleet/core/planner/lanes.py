"""Lanes: the route graph a site's operator draws, one-way or two-way (pure).

A site's lanes (:class:`fleet.core.site.Lane`) are polylines robots drive along; a one-way
lane only from its first point towards its last. Lanes meet where they share a point. When
a site has lanes, a robot's route (:meth:`LaneMap.route`) is:

* from where it stands to a point of a lane it sees (its straight way there keeps the
  clearance it has, :meth:`fleet.core.planner.roadmap.Roadmap.sees`; lanes are taken in
  steps of ``LANE_STEP_M``, so a robot gets on and off near where it is), along the lanes --
  with their direction (at least one step of a one-way lane, so none is crossed against its
  flow) -- to a lane point the pre-bay point sees, then the pre-bay point
  (``approach_m`` in front of the bay) and the paper's law for the last leg; the shortest
  such way (metres driven), its via-points where it turns, gets on or gets off;
* straight to its goal when that way is clear of every wall and post (as without lanes:
  lanes lead robots round walls, a robot with open floor to its bay drives straight);
  otherwise the lanes are the way, also when they lead round (a lane a wall was put
  across is cut there): that is what lanes are for;
* a lane step that an obstacle now blocks (a wall put across it with ``PUT /obstacles``)
  is no way;
* where the lanes give no way (a bay no lane point sees, a robot off every lane), the free
  space's route graph's way (:mod:`fleet.core.planner.roadmap`), so a lane map never makes
  a reachable bay unreachable.

World frame, metres. Without lanes, :func:`route_graph` is the free space's roadmap itself.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence
from typing import Protocol

import networkx as nx
import numpy as np

from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.roadmap import Point, Roadmap, pre_bay_point, roadmap_of, roundabouts
from fleet.core.route import LaneShape
from fleet.core.types import BoolArray, FloatArray
from fleet.core.wire import Obstacle

#: Lane points closer than this [m] are one junction.
JUNCTION_M = 1e-3
#: [m] the longest step between the lane points a robot may get on or off at.
LANE_STEP_M = 1.0
_SOURCE, _SINK = (-1, -1), (-2, -2)


class RouteGraph(Protocol):
    """What routing needs of a route graph (:class:`Roadmap`, :class:`LaneMap`)."""

    def route(
        self, start: Point, goal: tuple[float, float, float], approach_m: float
    ) -> tuple[Point, ...] | None: ...

    def clear(self, a: Point, b: Point, clearance_m: float) -> bool: ...


class LaneMap:
    """Routes along lanes (see the module docstring); build with :func:`route_graph`."""

    def __init__(self, roadmap: Roadmap, lanes: Sequence[LaneShape]) -> None:
        self.roadmap = roadmap
        nodes: list[Point] = []
        index: dict[tuple[int, int], int] = {}  # junctions: points on one JUNCTION_M cell
        graph = nx.DiGraph()  # (node, 0): not yet on a lane; (node, 1): driven one leg

        def node(p: Point) -> int:
            key = (round(p[0] / JUNCTION_M), round(p[1] / JUNCTION_M))
            if key not in index:
                index[key] = len(nodes)
                nodes.append(p)
            return index[key]

        # the clearance a site's lane must keep (fleet.core.site): the route's, less its slack
        keep = max(0.0, roadmap.clearance_m - PlannerConfig().route_slack_m)

        def leg(a: int, b: int) -> None:
            if not roadmap.clear(nodes[a], nodes[b], keep):
                return  # an obstacle put across the lane since (PUT /obstacles): not a way
            length = math.dist(nodes[a], nodes[b])
            graph.add_edge((a, 0), (b, 1), length=length)
            graph.add_edge((a, 1), (b, 1), length=length)

        for lane in lanes:
            ids = [node(p) for p in _stepped(lane.points)]
            for a, b in itertools.pairwise(ids):
                leg(a, b)
                if not lane.one_way:
                    leg(b, a)
            if not lane.one_way:  # a two-way lane's point may be touched and left at once
                for a in ids:
                    graph.add_edge((a, 0), (a, 1), length=0.0)
        self.nodes: FloatArray = np.array(nodes, dtype=np.float64).reshape(-1, 2)
        self.graph = graph

    def clear(self, a: Point, b: Point, clearance_m: float) -> bool:
        return self.roadmap.clear(a, b, clearance_m)

    def route(
        self, start: Point, goal: tuple[float, float, float], approach_m: float
    ) -> tuple[Point, ...] | None:
        """Via-points [m] for a robot at ``start`` to park at ``goal`` (x, y, heading
        [rad]): ``()`` straight, the lanes' way, else the free space's (module docstring);
        None: no way at all."""
        free = self.roadmap.route(start, goal, approach_m)
        if free == ():
            return free  # the straight way is clear: lanes lead round walls, not across floor
        s = (float(start[0]), float(start[1]))
        g = (float(goal[0]), float(goal[1]))
        p = pre_bay_point(goal, approach_m)
        for end in ((p, True), (g, False)) if approach_m > 0.0 else ((g, False),):
            target, pre_bay = end
            if pre_bay and not self.roadmap.clear(target, g, self.roadmap.end_clearance(g)):
                continue
            via = self._along(s, target)
            if via is None:
                continue
            return (*via, target) if pre_bay else via
        return free

    def _along(self, s: Point, t: Point) -> tuple[Point, ...] | None:
        """The lane points [m] of the shortest way from ``s`` onto the lanes, along them (in
        their direction: a one-way lane only after at least one step along it, so it is
        never crossed against its flow by touching one point; a two-way lane's point may
        be touched and left), and off them to ``t`` (both excluded), or None."""
        if len(self.nodes) == 0:
            return None
        on: BoolArray = self.roadmap.sees(s, self.nodes)
        off: BoolArray = self.roadmap.sees(t, self.nodes)
        if not on.any() or not off.any():
            return None
        graph = self.graph.copy()
        for k in np.flatnonzero(on):
            graph.add_edge(_SOURCE, (int(k), 0), length=math.dist(s, tuple(self.nodes[k])))
        for k in np.flatnonzero(off):
            graph.add_edge((int(k), 1), _SINK, length=math.dist(t, tuple(self.nodes[k])))
        try:
            path = nx.dijkstra_path(graph, _SOURCE, _SINK, weight="length")
        except nx.NetworkXNoPath:
            return None
        points: list[Point] = []
        for n, _ in path[1:-1]:  # a point touched and left at once is one via-point
            p = (float(self.nodes[n, 0]), float(self.nodes[n, 1]))
            if not points or points[-1] != p:
                points.append(p)
        return tuple(_turns(points))


def _stepped(points: Sequence[Point]) -> list[Point]:
    """``points`` with each leg cut into steps of at most ``LANE_STEP_M``."""
    out = [points[0]]
    for a, b in itertools.pairwise(points):
        n = max(1, math.ceil(math.dist(a, b) / LANE_STEP_M - 1e-9))
        out += [
            (a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n) for k in range(1, n + 1)
        ]
    return out


def _turns(points: list[Point]) -> list[Point]:
    """``points`` without those in the middle of a straight stretch (the first and the
    last are kept: where the robot gets on and off)."""
    out = points[:1]
    for k in range(1, len(points) - 1):
        a, b, c = out[-1], points[k], points[k + 1]
        cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
        if abs(cross) > 1e-9 * max(1.0, math.dist(a, b) * math.dist(b, c)):
            out.append(b)
    return out + points[-1:] if len(points) > 1 else out


class RoundaboutRoutes:
    """Routes round every lone obstacle's Eq. (27) zone where there is such a way, else
    round its body (see :func:`route_graph`); both are free-space roadmaps."""

    def __init__(self, round_zones: Roadmap, plain: Roadmap) -> None:
        self.round_zones = round_zones
        self.plain = plain

    def route(
        self, start: Point, goal: tuple[float, float, float], approach_m: float
    ) -> tuple[Point, ...] | None:
        """The way round the zones when it keeps the clearances the way round the bodies
        keeps (a start or a goal at a grown zone's edge would let it graze another body:
        :meth:`Roadmap.keeps`), else the way round the bodies."""
        way = self.round_zones.route(start, goal, approach_m)
        if way is not None and self.plain.keeps(start, goal, approach_m, way):
            return way
        return self.plain.route(start, goal, approach_m)

    def clear(self, a: Point, b: Point, clearance_m: float) -> bool:
        return self.plain.clear(a, b, clearance_m)


def route_graph(
    obstacles: tuple[Obstacle, ...], clearance_m: float, lanes: tuple[LaneShape, ...] = (),
    *, one_way: bool = False,
) -> RouteGraph:  # fmt: skip
    """The route graph robots are routed on: the free space's roadmap
    (:func:`~fleet.core.planner.roadmap.roadmap_of`), along ``lanes`` when there are any.

    Without lanes, round an island standing alone -- a post, or a short wall segment touching
    no other (:func:`~fleet.core.planner.roadmap.roundabouts`) -- the way keeps ``clearance_m`` [m]
    from its Eq. (27) influence zone, not only from its body: a robot's via-points inside
    the zone are where -K_avoid/x_OA holds it short of them. Where no such way exists (a
    start or a goal inside a zone, a zone closing a passage), the way round the bodies is
    taken, so the zones never make a goal unreachable. A site's lanes are the operator's
    ways and are driven as drawn. ``one_way``: round an island the way clockwise is taken
    only where it is much shorter (``ONE_WAY_PRICE`` instead of ``ROUNDABOUT_PRICE``: the
    robots a stuck recovery sends round the posts' zones, which would meet head-on there)."""
    if lanes:
        return _lane_map(obstacles, clearance_m, lanes)
    plain = roadmap_of(obstacles, clearance_m, one_way=one_way)
    grown = roundabouts(obstacles, clearance_m)
    if grown is obstacles:
        return plain
    return RoundaboutRoutes(roadmap_of(grown, clearance_m, one_way=one_way), plain)


@functools.lru_cache(maxsize=8)
def _lane_map(
    obstacles: tuple[Obstacle, ...], clearance_m: float, lanes: tuple[LaneShape, ...]
) -> LaneMap:
    return LaneMap(roadmap_of(obstacles, clearance_m), lanes)


__all__ = ["LaneMap", "LaneShape", "RoundaboutRoutes", "RouteGraph", "route_graph"]
