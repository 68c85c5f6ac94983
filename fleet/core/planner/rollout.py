"""Closed-loop rollouts of many small scenes in few simulator calls (pure).

A *scene* (:class:`Rows`) is a handful of robots that interact: each row is a robot with
its start and goal postures, gains, law, tolerance and start delay; a robot standing still
(parked, idle, lost or held) is a row whose goal is its start. :func:`roll_out` packs many
scenes into one :class:`fleet.core.simulate.BatchProblem` and simulates them as independent
groups (``simulate(group=...)``: peers repel, and separations are tracked, only within a
scene), so the planner's candidates cost one call, not one each.

Scenes of different sizes are padded to a common group size with inert rows: standing far
away from everything and from each other (beyond every influence radius), done at the first
step. Scenes share one world: they are not offset, so every scene sees the same static
obstacles (Eq. 27) -- group isolation is what keeps them apart. Scenes are bucketed by
padded size (at most 1.5x padding) and chunked to ``max_rows`` rows per call. A scene's
outcome does not depend on its partners in a call: one whose robots are all done ends at
its last arrival, even if the call went on.

A :class:`Live` rollout advances in segments (:func:`advance`): between segments the
planner stops candidates that are unsafe or can no longer win; segments change nothing
else (the simulator's state is the poses, which robots are done and the time elapsed).

The step is the agents' control step (``dt``) and the model is the robots' own: the same
simulator the fleet's agents are checked against, wheel limits, Eq. (27) repulsion from
peers and static obstacles.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from fleet.core.params import Avoidance, RobotProfile, SafetyConfig
from fleet.core.route import LaneShape
from fleet.core.simulate import BatchProblem, SimResult, batch_filter, obstacle_columns, simulate
from fleet.core.types import BoolArray, FloatArray, IntArray
from fleet.core.wire import DEFAULT_PASS_M, Obstacle

#: Padded group sizes (a scene of n rows runs in the smallest bucket >= n).
_BUCKETS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512)
#: Where inert padding rows stand [m]: far from any yard, 10 m apart (beyond any influence).
_PAD_X, _PAD_STEP = 1.0e6, 10.0
#: The via-point rows of a robot without a route.
NO_ROUTE = np.zeros((0, 2))
#: Tolerance of a standing row [m], [rad]: it is done at once.
STANDING_TOLERANCE = (1e-3, 1e-3)
#: Start delay of a standing row [s]: it never moves. A row done at a call's first step
#: still has that step applied, repulsion included, so without the delay a standing robot
#: beside a peer would be nudged at every call (and every segment); real agents that are
#: idle, arrived or held do not move at all.
STANDING_DELAY = math.inf


@dataclass(frozen=True)
class Rows:
    """One scene: ``n`` robots as arrays (world frame; metres, radians, seconds).

    ``gains`` (n, 3) = (kx, ky, ktheta); ``cw`` True for law (20); ``tolerance`` (n, 2) =
    (position [m], heading [rad]); ``delay`` (n,) start delay [s]; ``limits`` (n, 4) each
    robot's own profile (wheel radius [m], half axle [m], max wheel speed [rad/s], body
    radius [m]; :func:`limits_of`), a NaN row (or None for all) = the world's profile.
    ``route`` (n entries or None for all): each robot's via-points (m_i, 2) [m]
    (:mod:`fleet.core.route`), an empty (0, 2) = straight to its goal.
    """

    start: FloatArray  # (n, 3)
    goal: FloatArray  # (n, 3)
    gains: FloatArray  # (n, 3)
    cw: BoolArray  # (n,)
    tolerance: FloatArray  # (n, 2)
    delay: FloatArray  # (n,)
    limits: FloatArray | None = None  # (n, 4); None or NaN rows: the world's profile
    route: tuple[FloatArray, ...] | None = None

    @property
    def size(self) -> int:
        return int(self.start.shape[0])

    def routes(self) -> tuple[FloatArray, ...]:
        """Each robot's via-points (m_i, 2) (none: (0, 2))."""
        return self.route if self.route is not None else (NO_ROUTE,) * self.size

    @staticmethod
    def standing(
        xy: FloatArray, heading: FloatArray | None = None, limits: FloatArray | None = None
    ) -> Rows:
        """Robots standing still at ``xy`` (m, 2) [m] facing ``heading`` (m,) [rad] (None:
        0; the safety filter's projected point of a peer lies ahead of it), with their own
        ``limits`` (m, 4) (None: the world's profile): done from the first step, never
        moving."""
        m = xy.shape[0]
        pose = np.zeros((m, 3))
        pose[:, :2] = xy
        if heading is not None:
            pose[:, 2] = heading
        return Rows(
            start=pose,
            goal=pose.copy(),
            gains=np.ones((m, 3)),
            cw=np.zeros(m, dtype=bool),
            tolerance=np.tile(STANDING_TOLERANCE, (m, 1)),
            delay=np.full(m, STANDING_DELAY),
            limits=limits,
        )

    @staticmethod
    def concat(parts: Sequence[Rows]) -> Rows:
        return Rows(
            start=np.concatenate([p.start for p in parts]),
            goal=np.concatenate([p.goal for p in parts]),
            gains=np.concatenate([p.gains for p in parts]),
            cw=np.concatenate([p.cw for p in parts]),
            tolerance=np.concatenate([p.tolerance for p in parts]),
            delay=np.concatenate([p.delay for p in parts]),
            route=(
                None
                if all(p.route is None for p in parts)
                else tuple(r for p in parts for r in p.routes())
            ),
            limits=(
                None
                if all(p.limits is None for p in parts)
                else np.concatenate(
                    [np.full((p.size, 4), np.nan) if p.limits is None else p.limits for p in parts]
                )
            ),
        )


def limits_of(profiles: Sequence[RobotProfile | None]) -> FloatArray:
    """(n, 4) :attr:`Rows.limits` of ``profiles`` (None: a NaN row, the world's)."""
    out = np.full((len(profiles), 4), np.nan)
    for i, p in enumerate(profiles):
        if p is not None:
            out[i] = (p.wheel_radius, p.half_axle, p.max_wheel_speed, p.radius)
    return out


@dataclass(frozen=True)
class Outcome:
    """One scene's rollout. ``min_pair`` (n, n): closest centre distance of each pair over
    the run [m] (inf on the diagonal; None without peers); ``time`` [s] of arrival (NaN if
    not done); ``distance`` driven [m]; ``times`` (T,) and ``xy`` (T, n, 2): sampled positions
    when recorded."""

    min_pair: FloatArray | None
    done: BoolArray
    time: FloatArray
    final: FloatArray  # (n, 3)
    steps: int
    distance: FloatArray  # (n,) driven [m]
    times: FloatArray | None = None
    xy: FloatArray | None = None
    passed: IntArray | None = None  # (n,) via-points each robot passed (None: no routes)


@dataclass(frozen=True)
class World:
    """What every scene shares: the robots' profile, the repulsion and the static obstacles."""

    profile: RobotProfile
    avoidance: Avoidance
    obstacles: tuple[Obstacle, ...] = ()
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    #: [m] pass-through radius of the robots' via-points (``ParkAssignment.pass_m``).
    pass_m: float = DEFAULT_PASS_M
    #: the site's lanes: routes follow them (:mod:`fleet.core.planner.lanes`)
    lanes: tuple[LaneShape, ...] = ()


def _bucket(n: int) -> int:
    for b in _BUCKETS:
        if b >= n:
            return b
    return n


def _padding(m: int) -> Rows:
    xy = np.zeros((m, 2))
    xy[:, 0] = _PAD_X + _PAD_STEP * np.arange(m)
    return Rows.standing(xy)


def problem_of(rows: Rows, world: World, peers: bool = True) -> BatchProblem:
    """The batch problem of ``rows`` (tolerances as arrays: the problem's own columns)."""
    avoid = world.avoidance
    problem = BatchProblem.build(
        rows.start,
        rows.goal,
        rows.gains,
        rows.cw,
        profile=world.profile,
        **obstacle_columns(world.obstacles),
        k_avoid=avoid.k_avoid,
        peer_radius=avoid.peer_radius if peers else 0.0,
        min_x_oa=avoid.min_x_oa,
        smoothing=avoid.smoothing_m,
        start_delay=rows.delay,
        safety=batch_filter(world.safety),
        routes=None if rows.route is None else list(rows.route),
        pass_radius=world.pass_m,
    )
    problem = replace(
        problem,
        tol_position=np.ascontiguousarray(rows.tolerance[:, 0]),
        tol_heading=np.ascontiguousarray(rows.tolerance[:, 1]),
    )
    if rows.limits is None:
        return problem
    own = rows.limits

    def column(i: int, world_value: FloatArray | float | None) -> FloatArray:
        world_value = np.nan if world_value is None else world_value
        return np.ascontiguousarray(np.where(np.isnan(own[:, i]), world_value, own[:, i]))

    return replace(
        problem,
        wheel_radius=column(0, problem.wheel_radius),
        half_axle=column(1, problem.half_axle),
        max_wheel_speed=column(2, problem.max_wheel_speed),
        body_radius=column(3, problem.body_radius),
    )


def roll_out(
    scenes: Sequence[Rows],
    world: World,
    *,
    dt: float,
    max_time: float,
    peers: bool = True,
    record_every: int = 0,
    max_rows: int = 1024,
) -> list[Outcome]:
    """Simulate every scene on its own for up to ``max_time`` [s] (one outcome per scene,
    same order; a call stops early once all its robots are done).

    ``peers`` False: no robot repels another (solo rollouts; no ``min_pair``).
    ``record_every`` > 0: sample positions every that many steps (and the final one).
    """
    out: list[Outcome | None] = [None] * len(scenes)
    order = sorted(range(len(scenes)), key=lambda i: scenes[i].size)
    calls: list[tuple[int, list[int]]] = []
    for i in order:
        g = _bucket(scenes[i].size) if peers else scenes[i].size
        if calls and calls[-1][0] == g and (len(calls[-1][1]) + 1) * g <= max(max_rows, g):
            calls[-1][1].append(i)
        else:
            calls.append((g, [i]))
    for g, members in calls:
        if g == 0:
            for i in members:
                out[i] = _empty()
            continue
        parts: list[Rows] = []
        for i in members:
            parts.append(scenes[i])
            if peers and scenes[i].size < g:
                parts.append(_padding(g - scenes[i].size))
        result = simulate(
            problem_of(Rows.concat(parts), world, peers),
            dt=dt,
            max_time=max_time,
            track_separation=peers,
            group=g if peers else 0,
            record=record_every > 0,
            record_every=max(record_every, 1),
        )
        times: FloatArray | None = None
        if result.trajectory is not None:
            count = result.trajectory.poses.shape[0]
            times = np.arange(count, dtype=np.float64) * (record_every * dt)
            times[-1] = result.steps * dt
        offset = 0
        for i in members:
            n = scenes[i].size
            s = slice(offset, offset + n)
            offset += g if peers else n
            out[i] = _own(result, s, times, dt)
    return [o for o in out if o is not None]


def _own(result: SimResult, rows: slice, times: FloatArray | None, dt: float) -> Outcome:
    """One scene's share of a call: a scene whose robots were all done before the call
    ended (its partners kept it going) ends at its last arrival, as if alone."""
    done = result.done[rows]
    steps = result.steps
    if done.all() and done.size:
        steps = min(steps, round(float(np.max(result.time[rows])) / dt))
    xy = None
    if result.trajectory is not None and times is not None:
        keep = int(np.searchsorted(times, steps * dt - 1e-9))  # samples before the end
        xy = np.concatenate(
            [result.trajectory.poses[:keep, rows, :2], result.final_pose[None, rows, :2]]
        )
        times = np.append(times[:keep], steps * dt)
    return Outcome(
        min_pair=None
        if result.min_pair_distance is None
        else result.min_pair_distance[rows, rows].copy(),
        done=done.copy(),
        time=result.time[rows].copy(),
        final=result.final_pose[rows].copy(),
        steps=steps,
        distance=result.distance[rows].copy(),
        times=times,
        xy=xy,
        passed=None if result.passed is None else result.passed[rows].copy(),
    )


class Live:
    """A scene's rollout that can be advanced in segments (see :func:`advance`).

    Between segments its state is what the simulator's is between steps: poses, which
    robots are done (they stand), arrival times, the time elapsed (start delays count down
    from it) and the closest approach of every pair so far; positions are recorded every
    ``record_every`` steps.
    """

    def __init__(self, rows: Rows) -> None:
        n = rows.size
        self.rows = rows
        self.pose = rows.start.copy()
        self.done = np.zeros(n, dtype=bool)
        self.time = np.full(n, np.nan)
        self.min_pair = np.full((n, n), np.inf)
        self.elapsed = 0.0
        self.steps = 0
        self.distance = np.zeros(n)
        self.passed = np.zeros(n, dtype=np.int64)  # via-points passed (the routes go on)
        self.stopped = n == 0
        self._xy: list[FloatArray] = []
        self._times: list[FloatArray] = []

    def current(self) -> Rows:
        """The rest of the run as a fresh scene: done robots stand where they are, the others
        go on with the rest of their routes."""
        r, done = self.rows, self.done[:, None]
        route = None
        if r.route is not None:
            route = tuple(
                NO_ROUTE if d else via[p:]
                for via, p, d in zip(r.routes(), self.passed, self.done, strict=True)
            )
        return Rows(
            start=self.pose,
            goal=np.where(done, self.pose, r.goal),
            gains=r.gains,
            cw=r.cw,
            tolerance=np.where(done, STANDING_TOLERANCE, r.tolerance),
            delay=np.where(self.done, STANDING_DELAY, np.maximum(r.delay - self.elapsed, 0.0)),
            limits=r.limits,
            route=route,
        )

    def absorb(self, o: Outcome, dt: float) -> None:
        """Take one segment's outcome (simulated from :meth:`current`)."""
        fresh = o.done & ~self.done
        self.time[fresh] = self.elapsed + o.time[fresh]
        self.done |= o.done
        if o.min_pair is not None:
            np.minimum(self.min_pair, o.min_pair, out=self.min_pair)
        if o.xy is not None and o.times is not None:
            keep = slice(None) if o.steps == 0 else slice(None, -1)  # next segment's first
            self._xy.append(o.xy[keep])
            self._times.append(o.times[keep] + self.elapsed)
        self.pose = o.final
        self.distance += o.distance
        if o.passed is not None:
            self.passed += o.passed
        self.steps += o.steps
        self.elapsed = self.steps * dt
        if self.done.all():
            self.stopped = True

    def outcome(self) -> Outcome:
        """The rollout so far (positions recorded up to and including the last pose)."""
        xy = times = None
        if self._times:
            xy = np.concatenate([*self._xy, self.pose[None, :, :2]])
            times = np.concatenate([*self._times, [self.elapsed]])
        return Outcome(
            min_pair=self.min_pair,
            done=self.done.copy(),
            time=self.time.copy(),
            final=self.pose.copy(),
            steps=self.steps,
            distance=self.distance.copy(),
            times=times,
            xy=xy,
        )


def advance(
    lives: Sequence[Live],
    world: World,
    *,
    dt: float,
    duration: float,
    record_every: int = 0,
    max_rows: int = 1024,
) -> None:
    """Advance every live (not stopped) rollout by ``duration`` [s] in shared calls."""
    moving = [lv for lv in lives if not lv.stopped]
    if not moving:
        return
    outcomes = roll_out(
        [lv.current() for lv in moving],
        world,
        dt=dt,
        max_time=duration,
        record_every=record_every,
        max_rows=max_rows,
    )
    for lv, o in zip(moving, outcomes, strict=True):
        lv.absorb(o, dt)


def _empty() -> Outcome:
    return Outcome(
        min_pair=np.zeros((0, 0)),
        done=np.zeros(0, dtype=bool),
        time=np.zeros(0),
        final=np.zeros((0, 3)),
        steps=0,
        distance=np.zeros(0),
    )


__all__ = [
    "STANDING_DELAY",
    "STANDING_TOLERANCE",
    "Live",
    "Outcome",
    "Rows",
    "World",
    "advance",
    "problem_of",
    "roll_out",
]
