"""Single-robot zones in a plan: who may drive through which zone, in which order (pure).

Every mover's way -- from where the plan finds it (after the lead-in) through the rest of
its route to its goal (:func:`fleet.core.zones.way`) -- enters some zones
(:mod:`fleet.core.zones`). The movers are taken in order:

1. robots driving now (under way, not held: stopping them is what costs most);
2. then the robot nearest the zone along its way (it gets through soonest);
3. then the oldest task;

except that a robot whose every way passes another's goal goes before it
(:attr:`~fleet.core.planner.scene.Fleet.blocks`: once that one parks, it could not pass).

A mover whose zones are all free (or its own; in a zone that allows convoys, held only by
robots going its way) gets them for this plan, each with its pass
(:class:`fleet.core.zones.ZonePass`); the zones it takes are taken for every mover after it.
A mover one of whose zones another robot holds -- a robot standing in it, lost in it, one
earlier in the order, or in a convoy zone one going the other way -- must hold, unless it
stands in that zone itself (:func:`fleet.core.zones.may_join`: held there it would block the
zone for good -- a convoy's leader held at the far mouth, its way out bending off the
convoy's direction, blocked its followers behind it for 280 s in the corridor; it goes on,
out of it): it waits
where it stands, and its reason names the zone and the holder. A plan is made with those robots
held (:attr:`fleet.core.planner.scene.Movers.must_hold`); once the holder has left the zone
the service gives it back and plans again, and the next robot goes. Granting every zone of
a way at once, before the robot starts, means no robot ever holds one zone while it waits
for another: zones cannot deadlock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.types import BoolArray, FloatArray
from fleet.core.zones import ZonePass, ZoneShape, may_join, way


@dataclass(frozen=True)
class Gates:
    """The zones of each mover of a plan (indexed like :class:`~.scene.Movers`)."""

    granted: tuple[tuple[ZonePass, ...], ...]  # passes the mover holds if it moves
    must_hold: BoolArray  # (k,) it waits for a zone
    waits_for: tuple[str | None, ...]  # the zone it waits for
    reasons: tuple[str | None, ...]  # why it waits

    @staticmethod
    def none(k: int) -> Gates:
        """No zones: nobody waits for one."""
        return Gates(((),) * k, np.zeros(k, dtype=bool), (None,) * k, (None,) * k)


def blocked_first(preferred: Sequence[int], blocks: BoolArray) -> list[int]:
    """``preferred`` reordered so that every x with ``blocks[x, y]`` comes before y
    (depth first; a cycle keeps the preferred order)."""
    out: list[int] = []
    seen: set[int] = set()

    def place(y: int) -> None:
        seen.add(y)
        for x in preferred:
            if blocks[x, y] and x not in seen:
                place(x)
        out.append(y)

    for y in preferred:
        if y not in seen:
            place(y)
    return out


def holders_of(
    rows: Sequence[tuple[str, str, ZonePass | None]],
) -> dict[str, dict[str, ZonePass | None]]:
    """Zone -> robot -> pass, from the snapshot's (zone, robot, pass) rows."""
    out: dict[str, dict[str, ZonePass | None]] = {}
    for zone, robot, how in rows:
        out.setdefault(zone, {})[robot] = how
    return out


def gate(
    zones: Sequence[ZoneShape],
    holders: Mapping[str, Mapping[str, ZonePass | None]],
    robot_ids: Sequence[str],
    driving: BoolArray,
    start: FloatArray,
    routes: Sequence[FloatArray],
    goal: FloatArray,
    created_at: Sequence[float],
    blocks: BoolArray | None = None,
) -> Gates:
    """Grant zones to movers (see the module docstring).

    ``robot_ids``, ``driving`` (k,) whether each drives now (under way, not held),
    ``start`` (k, 3) [m, rad] where each stands when the plan reaches it, ``routes`` its via-points
    still to pass (m_i, 2) [m] (empty: none), ``goal`` (k, 3), ``created_at`` its task's
    creation time; ``holders`` zone -> robot -> its pass (None: it stands in the zone), the
    robots holding each zone now; ``blocks`` (k, k): mover x's
    every way passes mover y's goal (:attr:`~.scene.Fleet.blocks`): x goes first."""
    k = len(robot_ids)
    if not zones or k == 0:
        return Gates.none(k)
    ways = []
    needs: list[list[ZoneShape]] = []
    for i in range(k):
        via = routes[i] if i < len(routes) else np.zeros((0, 2))
        path = way(
            float(start[i, 0]),
            float(start[i, 1]),
            [(float(x), float(y)) for x, y in via],
            (float(goal[i, 0]), float(goal[i, 1])),
            rest=False,
        )
        ways.append(path)
        needs.append([z for z in zones if z.entered_by(path)])

    def order(i: int) -> tuple[bool, float, float, str]:
        first = min((z.distance_along(ways[i]) for z in needs[i]), default=math.inf)
        return (not bool(driving[i]), first, created_at[i], robot_ids[i])

    taken = {z: dict(h) for z, h in holders.items()}
    granted: list[tuple[ZonePass, ...]] = [()] * k
    must_hold = np.zeros(k, dtype=bool)
    waits_for: list[str | None] = [None] * k
    reasons: list[str | None] = [None] * k
    preferred = sorted((i for i in range(k) if needs[i]), key=order)
    if blocks is not None:
        preferred = blocked_first(preferred, blocks)
    for i in preferred:
        me = robot_ids[i]
        passes = [z.pass_of(ways[i]) for z in needs[i]]
        x, y = float(start[i, 0]), float(start[i, 1])
        blocked = [
            z
            for z, p in zip(needs[i], passes, strict=True)
            if p is None or not may_join(z, taken.get(z.name, {}), me, p, z.contains(x, y))
        ]
        if blocked:
            zone = blocked[0]
            held = {r: p for r, p in taken.get(zone.name, {}).items() if r != me}
            others = ", ".join(held)
            standing = any(p is None for p in held.values())  # in it: no way to name
            way_ = " going the other way" if zone.convoys and not standing else ""
            must_hold[i] = True
            waits_for[i] = zone.name
            reasons[i] = f"waiting for single-robot zone {zone.name} (held by {others}{way_})"
            continue
        granted[i] = tuple(p for p in passes if p is not None)
        for p in granted[i]:
            taken.setdefault(p.zone, {})[me] = p
    return Gates(tuple(granted), must_hold, tuple(waits_for), tuple(reasons))


__all__ = ["Gates", "blocked_first", "gate", "holders_of"]
