"""The planning problem of one snapshot: who may move, from where, and how (pure arrays).

A :class:`Fleet` holds

* the *movers*: robots with a task to decide -- ``NEW`` (a queued task just paired with an
  available robot), ``UNDER_WAY`` (driving, or in its start delay) and ``HELD`` (its task
  waits on a hold). Each has its goal, gains per law, tolerance, the laws it may use and
  what it does now (``keep_*``: law, remaining start delay, hold);
* the *standing* robots: every other robot of the snapshot (idle, arrived, holding, lost,
  and robots under way whose robot does not drive: ``holding``/``lost``). They stand
  still and repel like peers wherever a plan passes near them;
* the **lead-in**: the plan reaches the robots ``lead_time_s`` after the snapshot; until
  then the robots under way go on as they are (new robots stand), rolled out once for the
  whole fleet. Every candidate starts from the lead-in's end (``start``), and the
  separation during the lead-in is reported (no decision can change it);
* the **solo predictions**: each mover alone (static obstacles, no peers) with each law it
  may use, from ``start``: arrival times (lower bounds, horizons, default law), sampled
  paths (clusters) and which movers must pass before which others park (``blocks``);
* the **gates**: the single-robot zones each mover's way enters, and the movers that must
  hold because another robot holds (or goes first through) one of them
  (:mod:`~fleet.core.planner.gates`, ``Movers.must_hold``: every candidate holds them).

A :class:`Candidate` gives every mover of a cluster a law, a start delay and a hold flag;
:func:`scene_rows` turns it into the rows of one rollout (movers first, then standing).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from fleet.core.geometry import segment_distances, segments_distance
from fleet.core.planner.clusters import Cluster
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.gates import Gates, gate, holders_of
from fleet.core.planner.model import PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.planner.rollout import (
    NO_ROUTE,
    STANDING_DELAY,
    STANDING_TOLERANCE,
    Rows,
    World,
    limits_of,
    roll_out,
)
from fleet.core.route import remaining
from fleet.core.tasks import RobotStatus, TaskStatus
from fleet.core.types import LAWS, BoolArray, FloatArray, IntArray, Law
from fleet.core.wire import MAX_ROUTE_POINTS, Obstacle

#: [m] beyond the separation: a solo path this near another mover's goal is blocked once
#: that mover parks there (see ``Fleet.blocks``).
BLOCK_MARGIN_M = 0.1
#: [m] beyond the separation: a new robot whose every solo path passes this near a robot
#: standing there is stuck (the repulsion bends paths towards it by up to about this).
STUCK_MARGIN_M = 0.3
#: [m] beyond a post's influence radius: where the way round its Eq. (27) zone (a stalled
#: robot's, ``_wide``) keeps its via-points. Inside the zone's fade the term held a robot
#: short of a via-point at its edge (docs/benchmarks.md, ninth stop); the fade was 0.25 m
#: wide then, and the way round keeps that margin with the wider bands since.
ZONE_WAY_MARGIN_M = 0.25

NEW, UNDER_WAY, HELD = 0, 1, 2
LAW_INDEX: dict[Law, int] = {"ccw": 0, "cw": 1}
#: Task statuses of a task under way (it has a robot).
UNDER_WAY_STATUSES = (TaskStatus.ASSIGNED, TaskStatus.DRIVING, TaskStatus.WAITING)
#: Robots that do not drive whatever their task says: they stand.
_STILL = (RobotStatus.LOST, RobotStatus.HOLDING)


@dataclass(frozen=True)
class Movers:
    """The robots whose task the plan decides (k of them, arrays indexed by mover)."""

    tasks: tuple[TaskSnapshot, ...]
    robot_ids: tuple[str, ...]
    kind: IntArray  # NEW, UNDER_WAY or HELD
    start: FloatArray  # (k, 3) pose when the plan reaches the robot (after the lead-in)
    goal: FloatArray  # (k, 3)
    gains: FloatArray  # (k, 2, 3) per law index (0 ccw, 1 cw)
    tolerance: FloatArray  # (k, 2) position [m], heading [rad]
    allowed: BoolArray  # (k, 2) laws it may use
    keep_law: IntArray  # (k,) law it runs now (NEW: its fastest solo law)
    keep_delay: FloatArray  # (k,) start delay left when the plan arrives [s]
    keep_hold: BoolArray  # (k,) held now
    limits: FloatArray  # (k, 4) each robot's own profile (``Rows.limits``; NaN: the world's)
    #: each mover's via-points (m_i, 2) [m] (``Rows.route``; (0, 2): straight to its goal)
    route: tuple[FloatArray, ...] = ()
    #: (k,) movers on the last leg of the route they were sent: their route is empty because
    #: none of it is left (the robot keeps what it drives), not because it goes straight now
    last_leg: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    #: (k,) movers that must hold whatever the search finds: they wait for a single-robot
    #: zone (:mod:`fleet.core.planner.gates`); empty: none
    must_hold: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def size(self) -> int:
        return len(self.robot_ids)

    def routes(self, idx: IntArray, hold: BoolArray) -> tuple[FloatArray, ...] | None:
        """``Rows.route`` of movers ``idx`` (None: no mover has one)."""
        return _standing_still(self.route, idx, hold)


def _standing_still(
    route: Sequence[FloatArray], idx: IntArray, hold: BoolArray
) -> tuple[FloatArray, ...] | None:
    """``Rows.route`` of movers ``idx`` of ``route``; one that ``hold`` says stands has no
    route (None: no mover has one)."""
    if not route:
        return None
    return tuple(NO_ROUTE if h else route[i] for i, h in zip(idx, hold, strict=True))


@dataclass(frozen=True)
class Candidate:
    """One option per mover of a cluster: law index, start delay [s], hold."""

    law: IntArray
    delay: FloatArray
    hold: BoolArray

    def key(self) -> bytes:
        return self.law.tobytes() + self.delay.round(6).tobytes() + self.hold.tobytes()

    def with_(
        self, i: int, law: int | None = None, delay: float | None = None, hold: bool | None = None
    ) -> Candidate:
        """A copy with mover ``i``'s option changed."""
        c = Candidate(self.law.copy(), self.delay.copy(), self.hold.copy())
        if law is not None:
            c.law[i] = law
        if delay is not None:
            c.delay[i] = delay
        if hold is not None:
            c.hold[i] = hold
        return c


@dataclass(frozen=True)
class Fleet:
    """Everything a plan of one snapshot is searched on (see the module docstring)."""

    movers: Movers
    standing_ids: tuple[str, ...]
    standing_xy: FloatArray  # (s, 2)
    standing_heading: FloatArray  # (s,) [rad]
    standing_limits: FloatArray  # (s, 4), rows as ``Movers.limits``
    world: World
    separation: float  # [m]
    dt: float  # the agents' control step [s]
    lead_time: float  # [s]
    lead_min_separation: float  # [m] over the lead-in, pairs involving a moving robot
    solo_time: FloatArray  # (k, 2) [s]; inf where the law is not allowed or never arrives
    solo_times: FloatArray  # (T,) sample times of the solo paths [s]
    solo_xy: FloatArray  # (T, k, 2, 2) positions per sample, mover, law [m]
    #: (k, k): ``blocks[x, y]`` -- every law mover x may use passes its solo path within
    #: ``separation + BLOCK_MARGIN_M`` of mover y's goal: x must pass before y parks there
    blocks: BoolArray
    #: the single-robot zones each mover holds or waits for
    gates: Gates = field(default_factory=lambda: Gates.none(0))
    #: (k,) [s] each new mover's solo arrival through its open approach point (inf: none;
    #: :func:`_open_approaches`), whether or not it was given the point
    approach_time: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def top_speed(self) -> float:
        """[m/s] the slowest mover's top speed (the world's profile without movers): a
        remaining distance over it does not underestimate anyone's time."""
        speeds = [self.world.profile.max_speed] if self.movers.size == 0 else []
        wheel = self.movers.limits[:, 2] * self.movers.limits[:, 0]
        world = self.world.profile.max_speed
        speeds += [world if np.isnan(v) else float(v) for v in wheel]
        speed = min(speeds)
        return speed if np.isfinite(speed) and speed > 0 else 1.0

    def keep(self, movers: Sequence[int]) -> Candidate:
        """What the movers do now (new robots: their fastest law, no delay; a robot waiting
        for a zone holds)."""
        m = self.movers
        idx = np.asarray(movers, dtype=np.int64)
        hold = m.keep_hold[idx] | self.forced(idx)
        return Candidate(m.keep_law[idx].copy(), m.keep_delay[idx].copy(), hold)

    def forced(self, idx: IntArray) -> BoolArray:
        """(len(idx),) which of movers ``idx`` must hold (they wait for a zone)."""
        must = self.movers.must_hold
        return must[idx] if must.size else np.zeros(len(idx), dtype=bool)


def _start_delay_left(task: TaskSnapshot, robot: RobotSnapshot) -> float:
    if task.start_delay_left_s is not None:
        return max(0.0, task.start_delay_left_s)
    unknown_full = task.status == TaskStatus.ASSIGNED or robot.status == RobotStatus.WAITING
    return max(0.0, task.start_delay_s) if unknown_full else 0.0


def _gains(task: TaskSnapshot) -> FloatArray:
    rows = []
    for law in LAWS:
        g = task.gains.get(law) or next(iter(task.gains.values()))
        rows.append(g.as_tuple())
    return np.array(rows, dtype=np.float64)


def _allowed(task: TaskSnapshot) -> tuple[bool, bool]:
    if task.direction == "auto":
        return (True, True)
    return (task.direction == "ccw", task.direction == "cw")


def build_fleet(
    snapshot: PlanningSnapshot,
    pairs: Sequence[tuple[TaskSnapshot, RobotSnapshot]],
    config: PlannerConfig,
    approach: bool = True,
) -> Fleet:
    """The movers (tasks under way and the ``pairs`` of new assignments), the standing
    robots, the lead-in and the solo predictions of ``snapshot``; the new movers' open
    approach points found (``Fleet.approach_time``) and, with ``approach``, given."""
    robots = {r.robot_id: r for r in snapshot.robots}
    tasks: list[TaskSnapshot] = []
    owners: list[RobotSnapshot] = []
    kinds: list[int] = []
    for t in snapshot.tasks:
        if t.status not in UNDER_WAY_STATUSES or t.robot_id not in robots or t.law is None:
            continue
        robot = robots[t.robot_id]
        if robot.status in _STILL:
            continue
        tasks.append(t)
        owners.append(robot)
        kinds.append(HELD if t.hold else UNDER_WAY)
    for t, robot in pairs:
        tasks.append(t)
        owners.append(robot)
        kinds.append(NEW)
    k = len(tasks)
    moving_ids = {r.robot_id for r in owners}
    standing = [r for r in snapshot.robots if r.robot_id not in moving_ids]
    pose0 = np.array([r.pose for r in owners], dtype=np.float64).reshape(k, 3)
    kind = np.array(kinds, dtype=np.int64)
    law_now = np.array(
        [
            LAW_INDEX[t.law] if t.law is not None and kd != NEW else 0
            for t, kd in zip(tasks, kinds, strict=True)
        ],
        dtype=np.int64,
    )
    delay_now = np.array(
        [
            _start_delay_left(t, r) if kd == UNDER_WAY else 0.0
            for t, r, kd in zip(tasks, owners, kinds, strict=True)
        ],
        dtype=np.float64,
    )
    goal = np.array([t.goal for t in tasks], dtype=np.float64).reshape(k, 3)
    gains = np.array([_gains(t) for t in tasks], dtype=np.float64).reshape(k, 2, 3)
    tolerance = np.array(
        [(t.tolerance.position, t.tolerance.heading) for t in tasks], dtype=np.float64
    ).reshape(k, 2)
    allowed = np.array([_allowed(t) for t in tasks], dtype=bool).reshape(k, 2)
    limits = limits_of([r.profile for r in owners])
    standing_xy = np.array([r.pose[:2] for r in standing], dtype=np.float64).reshape(-1, 2)
    standing_heading = np.array([r.pose[2] for r in standing], dtype=np.float64)
    standing_limits = limits_of([r.profile for r in standing]).reshape(-1, 4)
    world = World(
        snapshot.profile, snapshot.avoidance, tuple(snapshot.obstacles), snapshot.safety,
        config.pass_m, snapshot.lanes,
    )  # fmt: skip
    standing_at = {r.robot_id: r.pose[:2] for r in standing}
    round_xy = [
        np.array([standing_at[r] for r in t.round_robots if r in standing_at], np.float64).reshape(
            -1, 2
        )
        for t in tasks
    ]
    route, last_leg = _routes(
        pose0, goal, limits, world, config, [t.route for t in tasks], [t.own_way for t in tasks],
        standing_xy, [t.wide_way for t in tasks], np.array([t.gave_way for t in tasks], bool),
        round_xy,
    )  # fmt: skip

    # Lead-in: robots under way go on as they are; new and held robots stand.
    driving = kind == UNDER_WAY
    start, lead_min = pose0.copy(), float("inf")
    lead = snapshot.lead_time_s
    if lead > 0 and driving.any():
        still = ~driving
        rows = Rows.concat(
            [
                Rows(
                    start=pose0,
                    goal=np.where(still[:, None], pose0, goal),
                    gains=gains[np.arange(k), law_now],
                    cw=law_now == 1,
                    tolerance=np.where(still[:, None], STANDING_TOLERANCE, tolerance),
                    delay=np.where(still, STANDING_DELAY, delay_now),
                    limits=limits,
                    route=_standing_still(route, np.arange(k), still),
                ),
                Rows.standing(standing_xy, standing_heading, standing_limits),
            ]
        )
        (result,) = roll_out([rows], world, dt=snapshot.control_dt, max_time=lead)
        start = result.final[:k].copy()
        start[still] = pose0[still]
        assert result.min_pair is not None
        involved = np.zeros(rows.size, dtype=bool)
        involved[:k] = driving
        pairs_involved = involved[:, None] | involved[None, :]
        if pairs_involved.any():
            lead_min = float(np.min(np.where(pairs_involved, result.min_pair, np.inf)))
        delay_now = np.maximum(delay_now - lead, 0.0)

    def solo(
        idx: IntArray, routes: Sequence[FloatArray]
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Movers ``idx`` alone on ``routes`` (:func:`_solo`)."""
        return _solo(
            start[idx], goal[idx], gains[idx], tolerance[idx], allowed[idx], world,
            snapshot.control_dt, config, limits[idx], routes,
        )  # fmt: skip

    everyone = np.arange(k)
    solo_time, solo_times, solo_xy = solo(everyone, route)
    drivable = _drivable(route, solo_time, solo)
    if drivable is not None:  # a route dropped: every solo again, on one time grid
        route = drivable
        solo_time, solo_times, solo_xy = solo(everyone, route)
    approached, approach_time = _open_approaches(
        route, kind, start, goal, limits, world, config, solo_time, solo
    )  # fmt: skip
    if approach and approached is not None:  # every solo again, on one time grid
        route = approached
        solo_time, solo_times, solo_xy = solo(everyone, route)
    fastest = np.where(
        allowed[:, 0] & (~allowed[:, 1] | (solo_time[:, 0] <= solo_time[:, 1])), 0, 1
    )
    blocks = _blocks(solo_xy, allowed, goal, snapshot.separation_m + BLOCK_MARGIN_M)
    gates = gate(
        snapshot.zones,
        holders_of(snapshot.zone_holders),
        [r.robot_id for r in owners],
        kind == UNDER_WAY,
        start,
        route or [NO_ROUTE] * k,
        goal,
        [t.created_at for t in tasks],
        blocks,
    )
    keep_law = np.where(kind == NEW, fastest, law_now)
    movers = Movers(
        tasks=tuple(tasks),
        robot_ids=tuple(r.robot_id for r in owners),
        kind=kind,
        start=start,
        goal=goal,
        gains=gains,
        tolerance=tolerance,
        allowed=allowed,
        keep_law=keep_law.astype(np.int64),
        keep_delay=delay_now,
        keep_hold=kind == HELD,
        limits=limits,
        route=route,
        last_leg=last_leg,
        must_hold=gates.must_hold,
    )
    return Fleet(
        movers=movers,
        standing_ids=tuple(r.robot_id for r in standing),
        standing_xy=standing_xy,
        standing_heading=standing_heading,
        standing_limits=standing_limits,
        world=world,
        separation=snapshot.separation_m,
        dt=snapshot.control_dt,
        lead_time=max(lead, 0.0),
        lead_min_separation=lead_min,
        solo_time=solo_time,
        solo_times=solo_times,
        solo_xy=solo_xy,
        blocks=blocks,
        gates=gates,
        approach_time=approach_time,
    )


def _open_approaches(
    route: Sequence[FloatArray],
    kind: IntArray,
    start: FloatArray,
    goal: FloatArray,
    limits: FloatArray,
    world: World,
    config: PlannerConfig,
    solo_time: FloatArray,
    solo: Callable[[IntArray, Sequence[FloatArray]], tuple[FloatArray, FloatArray, FloatArray]],
) -> tuple[tuple[FloatArray, ...] | None, FloatArray]:
    """Every mover's route with an approach point for the new movers that drive straight
    (:class:`PlannerConfig`, open approaches), or None when none is given one; and (k,)
    each mover's solo arrival time through its point [s] (inf: none).

    A candidate point lies ``d`` of ``config.open_approach_m`` [m] in front of the goal on
    its axis; it is tried for a new mover without a route that is behind its goal by more
    than ``d`` + ``pass_m`` (so it passes the point before it reaches the goal) and whose
    two straight legs keep its body the route clearance from every static body. Each is
    rolled out alone (``solo``; ``solo_time`` (k, 2) are the times without) and the fastest
    point is kept when, with its fastest law, it arrives more than
    ``config.open_approach_gain_s`` sooner."""
    k = start.shape[0]
    times = np.full(k, np.inf)
    if k == 0 or not config.open_approach_m:
        return None, times
    routes = list(route) if route else [NO_ROUTE] * k
    axis = np.stack([np.cos(goal[:, 2]), np.sin(goal[:, 2])], axis=1)  # (k, 2)
    behind = -((start[:, :2] - goal[:, :2]) * axis).sum(axis=1)  # [m] along the axis
    clearance = route_clearance(limits, world, config)
    rows: list[int] = []
    points: list[FloatArray] = []
    for d in config.open_approach_m:
        for i in range(k):
            if kind[i] != NEW or len(routes[i]) or behind[i] <= d + config.pass_m:
                continue
            point = goal[i, :2] - d * axis[i]
            if _legs_clear(start[i, :2], point, goal[i, :2], world.obstacles, clearance):
                rows.append(i)
                points.append(point.reshape(1, 2))
    if not rows:
        return None, times
    idx = np.asarray(rows, dtype=np.int64)
    with_point = solo(idx, points)[0].min(axis=1)  # (r,) [s] fastest law
    best_now = solo_time.min(axis=1)
    chosen: dict[int, tuple[float, FloatArray]] = {}
    for row, i in enumerate(rows):
        t = float(with_point[row])
        if t < best_now[i] - config.open_approach_gain_s and t < chosen.get(i, (math.inf,))[0]:
            chosen[i] = (t, points[row])
    if not chosen:
        return None, times
    for i, (t, point) in chosen.items():
        routes[i] = point
        times[i] = t
    return tuple(routes), times


def _legs_clear(
    start: FloatArray,
    point: FloatArray,
    goal: FloatArray,
    obstacles: Sequence[Obstacle],
    clearance: float,
) -> bool:
    """Whether the legs ``start`` -> ``point`` -> ``goal`` (x, y) [m] keep ``clearance``
    [m] from every obstacle's body."""
    s, p, g = ((float(v[0]), float(v[1])) for v in (start, point, goal))
    for o in obstacles:
        near, far = (o.x, o.y), o.far_end
        for a, b in ((s, p), (p, g)):
            if segments_distance(a, b, near, far) < o.body_radius + clearance:
                return False
    return True


def _routes(
    pose: FloatArray,
    goal: FloatArray,
    limits: FloatArray,
    world: World,
    config: PlannerConfig,
    sent: Sequence[Sequence[tuple[float, float]]],
    own_way: Sequence[bool],
    standing_xy: FloatArray,
    wide_way: Sequence[bool],
    gave_way: BoolArray,
    round_xy: Sequence[FloatArray] = (),
) -> tuple[tuple[FloatArray, ...], BoolArray]:
    """Each mover's via-points (m_i, 2) from ``pose`` (k, 3) to ``goal`` (k, 3) around the
    static obstacles: the rest of the route its robot was ``sent`` while its body's straight
    way to the next via-point is clear (the robot drives it: re-routing a robot beside a
    wall from scratch can send it another way), none once it is on the last leg with its
    goal in sight (:func:`fleet.core.route.remaining` with the goal: sending the last
    via-point again would turn it back to a point it has passed), else a new one from where
    it is (pushed off its route by its peers) (:mod:`fleet.core.planner.roadmap`); (0, 2)
    where the straight way is clear, there are no obstacles, or no route exists (the robot
    then drives straight and its safety filter stops it at the obstacle; the API refuses
    such goals) or a stuck recovery took the mover off its route (``own_way``: the law's
    own way). A route whose legs to its via-points pass a robot standing at
    ``standing_xy`` (s, 2) [m] closer than two bodies and the contact margin (an idle robot
    on a lane, beside a pre-bay point) or within a peer's influence radius of a via-point
    goes round it (:func:`_round_standing`): the robot could never reach that via-point.
    A mover a stuck recovery found stalled without a route (``wide_way``) is routed round
    the posts' Eq. (27) zones, not only their bodies (:func:`_wide`). A mover whose way
    -- its last leg too -- passes a robot standing still (one that ``gave_way`` (k,) in a
    standoff, or any at ``standing_xy`` unless it drives its ``own_way``) goes round that
    robot (:func:`_round_givers`): the laws drive straight at a robot standing dead ahead,
    and Eq. (27) only slows them; so does a mover round the standing
    robots at ``round_xy[i]`` (g_i, 2) [m] that held it off in a standoff. Also which movers
    are on their last leg (``Movers.last_leg``)."""
    k = pose.shape[0]
    last_leg = np.zeros(k, dtype=bool)
    rounds = any(len(r) for r in round_xy)
    radii = np.where(np.isnan(limits[:, 3]), world.profile.radius, limits[:, 3])
    reach = radii + world.profile.radius + world.safety.contact_margin_m  # (k,) [m]
    if (
        k == 0
        or not (
            world.obstacles
            or any(len(s) for s in sent)  # an approach point in open space (kept, below)
            or gave_way.any()
            or rounds  # else: a robot standing on a mover's straight way, (s, k) distances
            or (segment_distances(standing_xy[None], pose[:, :2], goal[:, :2])[0] < reach).any()
        )
    ):
        return (), last_leg
    # shapely and networkx on first use: the fleet service plans with them, a robot never.
    from fleet.core.planner.lanes import route_graph

    clearance = route_clearance(limits, world, config)
    plain = route_graph(world.obstacles, clearance, world.lanes)
    wide = _wide(world.obstacles, clearance) if any(wide_way) else ()
    wide_map = route_graph(wide, clearance, world.lanes, one_way=True) if wide else plain
    out = []
    for i in range(k):
        roadmap = wide_map if wide_way[i] else plain
        here = (float(pose[i, 0]), float(pose[i, 1]))
        target = (float(goal[i, 0]), float(goal[i, 1]), float(goal[i, 2]))
        if own_way[i]:
            out.append(NO_ROUTE)
            continue
        if sent[i]:
            rest = remaining(sent[i], *here, target[:2])
            if not len(rest) and roadmap.clear(here, target[:2], float(radii[i])):
                out.append(NO_ROUTE)  # on the last leg: the paper's law parks it
                last_leg[i] = True
                continue
            rest = rest if len(rest) else remaining(sent[i], *here)
            if roadmap.clear(here, (rest[0, 0], rest[0, 1]), float(radii[i])) and not len(
                _in_the_way(here, rest, standing_xy, reach[i], world.avoidance.peer_radius)
            ):
                out.append(rest)  # still in sight of the next via-point: drive the rest
                continue
        points = roadmap.route(here, target, config.approach_m)
        if points is None and wide_way[i]:  # in a closed gap's mouth: back out first
            away = _backed_out(here, wide, clearance)
            after = None if away is None else roadmap.route(away, target, config.approach_m)
            if away is not None and after is not None:
                points = (away, *after)
        if points:
            points = _round_standing(
                points, here, target, standing_xy, reach[i], world, clearance, config,
                wide if wide_way[i] else world.obstacles, one_way=wide_way[i],
            )  # fmt: skip
        # At most what an assignment carries: a longer way is driven as far as that goes,
        # and routed again from there once the robot is out of the next point's sight.
        points = (points or ())[:MAX_ROUTE_POINTS]
        out.append(np.array(points, dtype=np.float64).reshape(-1, 2) if points else NO_ROUTE)
    givers = pose[gave_way, :2]
    for i in np.flatnonzero(~gave_way).tolist():
        blockers = np.vstack([givers, NO_ROUTE if own_way[i] else standing_xy])
        held_off = round_xy[i] if rounds else NO_ROUTE
        if not (len(blockers) or len(held_off)):
            continue
        around = _round_givers(
            out[i], pose[i], goal[i], blockers, standing_xy, float(reach[i]), world,
            clearance, config, wide if wide_way[i] else world.obstacles, one_way=wide_way[i],
            held_off=held_off,
        )  # fmt: skip
        if around is not None:
            out[i], last_leg[i] = around, False
    return tuple(out), last_leg


def route_clearance(limits: FloatArray, world: World, config: PlannerConfig) -> float:
    """[m] the clearance the movers' routes keep (:meth:`PlannerConfig.route_clearance` of
    the largest mover, ``limits`` (k, 4) as :attr:`Movers.limits`)."""
    radii = np.where(np.isnan(limits[:, 3]), world.profile.radius, limits[:, 3])
    return config.route_clearance(float(radii.max()), world.safety.contact_margin_m)


@functools.lru_cache(maxsize=8)
def _wide(obstacles: tuple[Obstacle, ...], clearance: float) -> tuple[Obstacle, ...]:
    """``obstacles`` with every post's body grown to its influence radius +
    ``ZONE_WAY_MARGIN_M`` less the route ``clearance`` [m], so that a route's
    via-points (``clearance`` beyond a body) lie outside the post's Eq. (27) zone and a gap
    whose middle two posts' zones cover is closed. Inside a zone the repulsion can hold a
    robot short of a via-point, and in such a gap's mouth the two posts' terms hold a robot
    driving the law for good (docs/benchmarks.md, ninth stop: case III with four robots).
    Walls keep their body (corridors stay open). Only for robots found stalled: the way
    round is longer, and robots sent round together meet each other there."""
    grown = ZONE_WAY_MARGIN_M - clearance  # [m] beyond the influence radius
    return tuple(
        o
        if o.end is not None or o.radius + grown <= o.body_radius
        else o.model_copy(update={"body": o.radius + grown})
        for o in obstacles
    )


def _backed_out(
    here: tuple[float, float], obstacles: Sequence[Obstacle], clearance: float
) -> tuple[float, float] | None:
    """The nearest point straight away from the posts whose body + ``clearance`` [m]
    ``here`` lies within (the sum of the directions from their centres), 0.1 m steps, up
    to 2 m; None: none within that (or nothing to back out of)."""
    hx, hy = here
    dx = dy = 0.0
    for o in obstacles:
        d = o.distance(hx, hy)
        if o.end is None and 0.0 < d < o.body_radius + clearance:
            dx, dy = dx + (hx - o.x) / d, dy + (hy - o.y) / d
    norm = math.hypot(dx, dy)
    if norm == 0.0:
        return None
    for k in range(1, 21):
        p = (hx + 0.1 * k * dx / norm, hy + 0.1 * k * dy / norm)
        if all(o.end is not None or o.distance(*p) >= o.body_radius + clearance for o in obstacles):
            return p
    return None


def _in_the_way(
    here: tuple[float, float], via: FloatArray | Sequence[tuple[float, float]],
    standing_xy: FloatArray, reach: float, influence: float,
    goal: tuple[float, float] | None = None,
) -> FloatArray:  # fmt: skip
    """Rows of ``standing_xy`` (s, 2) [m] a robot at ``here`` cannot drive its via-points
    ``via`` (m, 2) [m] past: closer than ``reach`` [m] (two bodies and the contact margin)
    to a leg from ``here`` through them, or within ``influence`` [m] (a peer's Eq. (27)
    radius) of a via-point -- the robot near its via-point with a peer ahead stalls where
    the repulsion -K_avoid/x_OA outweighs the law's kx x_e. The leg from the last via-point
    to the goal is left out unless ``goal`` (x, y) [m] is given: the paper's law drives it,
    bending round a peer beside it (not round one dead ahead)."""
    if standing_xy.shape[0] == 0:
        return standing_xy
    points = np.asarray(via, dtype=np.float64).reshape(-1, 2)
    last = () if goal is None else (np.asarray(goal, dtype=np.float64),)
    ends = np.vstack([np.asarray(here, dtype=np.float64), points, *last])
    on_leg = (segment_distances(standing_xy[None], ends[:-1], ends[1:])[0] < reach).any(axis=1)
    to_via = standing_xy[:, None, :] - points[None]
    at_via: BoolArray = ((to_via * to_via).sum(axis=2) < influence * influence).any(axis=1)
    blocked: FloatArray = standing_xy[on_leg | at_via]
    return blocked


#: [m] standing robots' positions are rounded to this grid (and their bodies grown by it)
#: before they join a route graph: the graph is cached by its obstacles, and a standing
#: robot's reported pose wanders with its pose noise.
STANDING_GRID_M = 0.05

#: [m] how much longer than the way round standing robots' shrunk bodies a way that backs
#: out of one's zone first may be (a way round a whole garage, its gate closed by a
#: standing robot's whole grown body, is no way round it).
ROUND_DETOUR_M = 4.0


def _round_standing(
    points: tuple[tuple[float, float], ...], here: tuple[float, float],
    target: tuple[float, float, float], standing_xy: FloatArray, reach: float, world: World,
    clearance: float, config: PlannerConfig, obstacles: tuple[Obstacle, ...],
    one_way: bool = False,
) -> tuple[tuple[float, float], ...]:  # fmt: skip
    """``points`` (a route from ``here`` to ``target`` round ``obstacles``: the world's, or
    :func:`_wide`'s for a robot routed round the posts' zones, ``one_way``), or, when
    standing robots are in its way (:func:`_in_the_way`), the route round them too
    (:func:`_route_round`). ``points`` when that graph has no way."""
    influence = world.avoidance.peer_radius
    blockers = _in_the_way(here, points, standing_xy, reach, influence)
    if blockers.shape[0] == 0:
        return points
    around = _route_round(here, target, blockers, world, clearance, config, obstacles, one_way)
    return points if around is None else around


def _route_round(
    here: tuple[float, float], target: tuple[float, float, float], blockers: FloatArray,
    world: World, clearance: float, config: PlannerConfig, obstacles: tuple[Obstacle, ...],
    one_way: bool = False,
) -> tuple[tuple[float, float], ...] | None:  # fmt: skip
    """The route from ``here`` to ``target`` of a graph of ``obstacles`` (``one_way``: see
    :func:`~fleet.core.planner.lanes.route_graph`) where the robots standing at
    ``blockers`` (b, 2) [m] are posts whose grown body (``clearance`` [m] beyond it, on a
    ``STANDING_GRID_M`` grid) holds their body and their peers' influence radius. A robot
    already within that of one backs straight out of it first (:func:`_backed_out`, when
    that way is clear of the obstacles): routed round it from where it is, its via-points
    would lie within the peer's Eq. (27) zone, where the repulsion holds it short of them
    (a robot 0.7 m behind a standing one stalled for good). Else -- or when that way is
    more than ``ROUND_DETOUR_M`` longer: the whole bodies closed a passage, as a garage's
    gate -- the bodies are shrunk (not below a body) so that ``here`` lies outside them.
    None: no way."""
    from fleet.core.planner.lanes import route_graph

    body = max(world.profile.radius, world.avoidance.peer_radius - clearance) + STANDING_GRID_M
    grid = np.round(blockers / STANDING_GRID_M) * STANDING_GRID_M
    near = np.hypot(grid[:, 0] - here[0], grid[:, 1] - here[1]) - clearance - STANDING_GRID_M
    posts = tuple(
        Obstacle(x=float(x), y=float(y), radius=b, body=b)
        for (x, y), b in zip(grid, np.clip(near, world.profile.radius, body), strict=True)
    )
    shrunk = route_graph(obstacles + posts, clearance, world.lanes, one_way=one_way).route(
        here, target, config.approach_m
    )
    whole = tuple(Obstacle(x=float(x), y=float(y), radius=body, body=body) for x, y in grid)
    away = _backed_out(here, whole, clearance + STANDING_GRID_M) if (near < body).any() else None
    if away is None or not route_graph(obstacles, clearance, world.lanes).clear(
        here, away, world.profile.radius
    ):
        return shrunk
    graph = route_graph(obstacles + whole, clearance, world.lanes, one_way=one_way)
    after = graph.route(away, target, config.approach_m)
    if after is None:
        return shrunk
    backed = (away, *after)
    goal = target[:2]
    if (
        shrunk is None
        or _way_length(here, backed, goal) <= _way_length(here, shrunk, goal) + ROUND_DETOUR_M
    ):
        return backed
    return shrunk  # the whole bodies close a passage the shrunk ones leave open


def _way_length(
    here: tuple[float, float], via: Sequence[tuple[float, float]] | FloatArray,
    goal: tuple[float, float],
) -> float:  # fmt: skip
    """[m] the polyline from ``here`` through ``via`` (m, 2) to ``goal``."""
    points = np.vstack([np.asarray(here), np.asarray(via).reshape(-1, 2), np.asarray(goal)])
    return float(np.hypot(*np.diff(points, axis=0).T).sum())


def _round_givers(
    way: FloatArray, pose: FloatArray, goal: FloatArray, givers: FloatArray,
    standing_xy: FloatArray, reach: float, world: World, clearance: float,
    config: PlannerConfig, obstacles: tuple[Obstacle, ...], one_way: bool = False,
    held_off: FloatArray = NO_ROUTE,
) -> FloatArray | None:  # fmt: skip
    """A way (m, 2) [m] for a mover at ``pose`` driving ``way`` (its via-points) to
    ``goal`` round the robots at ``givers`` (g, 2) [m] -- robots that gave way in a
    standoff, or stand -- when its way, the last leg included, passes one of them
    (:func:`_in_the_way` with the goal), and round the standing robots at ``held_off``
    (h, 2) [m] that held it off in a standoff when its way passes within their influence
    radius -- and round the ``standing_xy`` robots in the new way -- on a graph of
    ``obstacles`` (:func:`_route_round`, ``one_way``); None: none in its way, or no way
    round."""
    here = (float(pose[0]), float(pose[1]))
    target = (float(goal[0]), float(goal[1]), float(goal[2]))
    influence = world.avoidance.peer_radius
    ahead = np.vstack(
        [
            _in_the_way(here, way, givers, reach, influence, target[:2]),
            _in_the_way(here, way, held_off, max(reach, influence), influence, target[:2]),
        ]
    )
    if ahead.shape[0] == 0:
        return None
    around = _route_round(here, target, ahead, world, clearance, config, obstacles, one_way)
    if around:
        standing = _in_the_way(here, around, standing_xy, reach, influence)
        if standing.shape[0]:
            blockers = np.vstack([ahead, standing])
            around = _route_round(
                here, target, blockers, world, clearance, config, obstacles, one_way
            )
    if not around:
        return None
    return np.array(around[:MAX_ROUTE_POINTS], dtype=np.float64).reshape(-1, 2)


def stuck(fleet: Fleet) -> list[int]:
    """New movers whose every law passes a standing robot within ``separation +
    STUCK_MARGIN_M``: they would hold until that robot leaves."""
    m = fleet.movers
    if fleet.standing_xy.shape[0] == 0:
        return []
    reach = fleet.separation + STUCK_MARGIN_M
    d = fleet.solo_xy[:, :, :, None, :] - fleet.standing_xy[None, None, None]  # T,k,law,s,2
    near = ((d * d).sum(axis=4) < reach * reach).any(axis=(0, 3))  # (k, law)
    blocked = np.where(m.allowed, near, True).all(axis=1)
    return [int(i) for i in np.flatnonzero(blocked & (m.kind == NEW))]


def _blocks(solo_xy: FloatArray, allowed: BoolArray, goal: FloatArray, reach: float) -> BoolArray:
    """(k, k) which movers' solo paths (every law they may use) pass near which goals."""
    k = goal.shape[0]
    if k == 0:
        return np.zeros((0, 0), dtype=bool)
    d = solo_xy[:, :, :, None, :] - goal[None, None, None, :, :2]  # (T, k, law, k, 2)
    near = ((d * d).sum(axis=4) < reach * reach).any(axis=0)  # (k, law, k)
    out: BoolArray = np.asarray(np.where(allowed[:, :, None], near, True).all(axis=1))
    np.fill_diagonal(out, False)
    return out


def _drivable(
    route: tuple[FloatArray, ...],
    solo_time: FloatArray,
    solo: Callable[[IntArray, Sequence[FloatArray]], tuple[FloatArray, FloatArray, FloatArray]],
) -> tuple[FloatArray, ...] | None:
    """``route`` with the routes its robots cannot drive dropped (None: every route is
    kept): a mover that does not finish its route alone with any law (``solo_time`` (k,
    2)) drives straight where, alone (``solo``: movers alone on given routes), it arrives
    that way -- the paper's law and Eq. (27) take it round the obstacles, while a route
    threading a gap between two posts lies inside both repulsion zones, where the law
    stalls short of its via-points."""
    stalled = [i for i, r in enumerate(route) if len(r) and not np.isfinite(solo_time[i]).any()]
    if not stalled:
        return None
    idx = np.asarray(stalled, dtype=np.int64)
    straight_time, _, _ = solo(idx, [NO_ROUTE] * len(idx))
    arrives = np.isfinite(straight_time).any(axis=1)
    if not arrives.any():
        return None
    out = list(route)
    for i in idx[arrives]:
        out[int(i)] = NO_ROUTE
    return tuple(out)


def _solo(
    start: FloatArray,
    goal: FloatArray,
    gains: FloatArray,
    tolerance: FloatArray,
    allowed: BoolArray,
    world: World,
    dt: float,
    config: PlannerConfig,
    limits: FloatArray | None = None,
    route: Sequence[FloatArray] = (),
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Each mover alone with each allowed law: arrival times (k, 2) and sampled paths."""
    k = start.shape[0]
    solo_time = np.full((k, 2), np.inf)
    step = max(dt, config.solo_dt)
    every = max(1, round(config.sample_period_s / step))
    if k == 0:
        return solo_time, np.zeros(1), np.zeros((1, 0, 2, 2))
    rows = Rows(
        start=np.repeat(start, 2, axis=0),
        goal=np.repeat(goal, 2, axis=0),
        gains=gains.reshape(2 * k, 3),
        cw=np.tile([False, True], k),
        tolerance=np.repeat(tolerance, 2, axis=0),
        delay=np.zeros(2 * k),
        limits=None if limits is None else np.repeat(limits, 2, axis=0),
        route=tuple(r for r in route for _ in range(2)) if route else None,
    )
    (result,) = roll_out(
        [rows], world, dt=step, max_time=config.max_horizon_s, peers=False, record_every=every
    )
    times = result.time.reshape(k, 2)
    solo_time = np.where(allowed & result.done.reshape(k, 2), times, np.inf)
    assert result.xy is not None and result.times is not None
    xy = result.xy.reshape(-1, k, 2, 2)
    return solo_time, result.times, xy


def scene_rows(fleet: Fleet, cluster: Cluster, c: Candidate) -> Rows:
    """Rows of one rollout: the cluster's movers with option ``c``, then its standing robots,
    then its phantoms (:mod:`fleet.core.planner.clusters`).

    A held mover stands where it is (goal = start, done at once)."""
    m = fleet.movers
    idx = np.asarray(cluster.movers, dtype=np.int64)
    start = m.start[idx]
    hold = c.hold[:, None]
    rows = Rows(
        start=start,
        goal=np.where(hold, start, m.goal[idx]),
        gains=m.gains[idx, c.law],
        cw=c.law == 1,
        tolerance=np.where(hold, STANDING_TOLERANCE, m.tolerance[idx]),
        delay=np.where(c.hold, STANDING_DELAY, c.delay),
        limits=m.limits[idx],
        route=m.routes(idx, c.hold),
    )
    near = np.asarray(cluster.standing, dtype=np.int64)
    phantoms = np.array([p[:2] for p in cluster.phantoms], dtype=np.float64).reshape(-1, 2)
    fixed = np.concatenate([fleet.standing_xy[near].reshape(-1, 2), phantoms])
    if fixed.shape[0] == 0:
        return rows
    # phantoms (other clusters' movers where they start or end): heading 0, own limits
    heading = np.concatenate([fleet.standing_heading[near], np.zeros(len(phantoms))])
    limits = np.concatenate(
        [fleet.standing_limits[near].reshape(-1, 4), m.limits[[p[2] for p in cluster.phantoms]]]
    ).reshape(-1, 4)
    return Rows.concat([rows, Rows.standing(fixed, heading, limits)])


def row_names(fleet: Fleet, cluster: Cluster) -> list[str]:
    """Robot ids of the rows of :func:`scene_rows` (a phantom: "<id> where it stands")."""
    names = [fleet.movers.robot_ids[i] for i in cluster.movers]
    names += [fleet.standing_ids[j] for j in cluster.standing]
    names += [f"{fleet.movers.robot_ids[p[2]]} where it stands" for p in cluster.phantoms]
    return names


__all__ = [
    "BLOCK_MARGIN_M",
    "HELD",
    "LAW_INDEX",
    "NEW",
    "STUCK_MARGIN_M",
    "UNDER_WAY",
    "UNDER_WAY_STATUSES",
    "Candidate",
    "Fleet",
    "Movers",
    "build_fleet",
    "row_names",
    "scene_rows",
    "stuck",
]
