"""Metrics of one benchmark run, from time-aligned true poses (identical for every policy).

:class:`RunMetrics` is fed tick after tick -- every robot's true pose and mode at the same
simulated instant, from a ``parkfleet sim`` trace file or a navground run -- and keeps only
running figures, so memory stays bounded however long the run (paths are kept subsampled,
for plots). Definitions:

* **collision** -- a pair of robots whose centres are closer than the sum of their radii
  at the same instant (less :data:`COLLISION_SLACK_M`: navground's float32 positions read a
  graze at 0.4 m as 0.39999 m); ``collisions`` counts the pairs that ever touched, and
  every contact episode's first instant is kept (bounded) for plots;
* **minimum separation** -- the smallest centre distance of any pair at any instant [m];
* **obstacle hits** -- robots whose body ever overlapped a static obstacle's body
  (clearance = centre distance - robot radius - obstacle body < -slack);
* **arrival** -- of a task: the first instant its robot reports ``arrived`` within
  ``arrival_radius_m`` of the task's goal (a robot may serve several tasks in a run: a
  stream's later task can go to a robot that has already parked); success counts tasks,
  makespan is the last task's arrival from the run's start;
* **path ratio** -- per task that arrived: the distance its robot drove for it (true
  poses, every tick, from the robot's previous arrival or the run's start to this arrival)
  / the straight line from where that leg began to the task's goal; the mean over the
  tasks that arrived;
* **deadlock** -- a robot with a task, not arrived, not waiting on purpose (a planned start
  delay or hold, mode ``waiting``), farther than :data:`NEAR_GOAL_M` from its goal, whose
  distance to the goal has not dropped :data:`PROGRESS_M` below its best for
  :data:`DEADLOCK_WINDOW_S` simulated seconds (the clock restarts whenever it waits or
  enters the parking zone); counted once per robot, where and when it was found;
* **stops and cusps** (smoothness) -- on a trip (a robot's ticks between leaving a passive
  mode -- idle, arrived -- and entering one again; ``waiting``, a planned hold, is part of
  the trip), ``u`` is the true forward speed, the displacement between consecutive ticks
  along the heading over the time step [m/s]; the robot moves when ``|u| >=``
  :data:`MOVING_SPEED_M_S`. A *stop* is a standstill of at least :data:`STOP_MIN_S` between
  two moving ticks of the same trip (the start and the final standstill are not stops; a
  turn in place is a standstill); a *cusp* is a reversal of the sign of ``u`` between two
  moving ticks of the same trip, with or without a standstill between them. Counted per
  robot; the bench reports them per task (:meth:`RunResult.smoothness`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from fleet.core.geometry import segment_distances
from fleet.core.types import BoolArray, FloatArray, IntArray
from fleet.core.wire import Obstacle
from fleet.io.trace import NO_MODE, ModeArray, TraceChunk

#: Tolerance [m] of the contact test (float32 rounding of the peers' positions).
COLLISION_SLACK_M = 1e-4
#: A robot making no progress for this long [s, simulated] is deadlocked.
DEADLOCK_WINDOW_S = 10.0
#: Progress: the distance to the goal improves this much [m] on its best so far.
PROGRESS_M = 0.05
#: Within this distance of its goal [m] a robot is parking, not stuck (the laws' final
#: manoeuvres -- a full turn to fix a few centimetres -- take longer than the window).
NEAR_GOAL_M = 0.5
#: Contact episodes kept for plots.
MAX_EVENTS = 500
#: A task arrived when its robot reports ``arrived`` this close to the task's goal [m]:
#: robots stop within their position tolerance (0.1 m by default) of the pose they
#: measure, the true pose within the measurement noise; goals are 1.5 m apart or more.
ARRIVAL_RADIUS_M = 0.25
#: A robot moves when its true forward speed is at least this [m/s] (smoothness).
MOVING_SPEED_M_S = 0.02
#: A standstill inside a trip lasting at least this long [s, simulated] is a stop.
STOP_MIN_S = 0.2
#: Pair-distance entries computed at once (bounds the scratch memory).
_BLOCK = 1_000_000


def percentile(values: npt.ArrayLike, q: float) -> float:
    """The ``q``-th percentile of ``values``, NaN when there are none (every benchmark's)."""
    data = np.asarray(values, dtype=np.float64)
    return float(np.percentile(data, q)) if data.size else float("nan")


@dataclass(frozen=True)
class Event:
    """Something worth marking on a plot: time [s], robots involved, where (x, y) [m]."""

    t: float
    robots: tuple[int, ...]
    x: float
    y: float


@dataclass
class RunResult:
    """Figures of one run; robot indices follow the trace / scenario order."""

    ticks: int
    t_start: float
    t_last: float
    collision_pairs: int
    collisions: list[Event]
    min_separation_m: float | None
    obstacle_hits: int
    min_obstacle_clearance_m: float | None
    arrivals: FloatArray  # (N,) time a robot first reported arrived [s], NaN if never
    driven: FloatArray  # (N,) distance driven [m]
    starts: FloatArray  # (N, 3) pose at the run's start
    goals: FloatArray  # (N, 3) goal, NaN rows for robots without a task
    deadlocks: list[Event]
    path_t: FloatArray  # (S,) subsampled times [s]
    paths: FloatArray  # (S, N, 3) subsampled true poses
    final: FloatArray  # (N, 3) last true pose
    task_arrivals: FloatArray  # (T,) time each task arrived [s], NaN if never
    task_driven: FloatArray = field(default_factory=lambda: np.zeros(0))  # (T,) [m], NaN
    task_straight: FloatArray = field(default_factory=lambda: np.zeros(0))  # (T,) [m], NaN
    stops: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # (N,)
    cusps: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # (N,)

    @property
    def tasked(self) -> BoolArray:
        return np.asarray(~np.isnan(self.goals[:, 0]))

    def success_count(self) -> int:
        """Tasks that arrived."""
        return int(np.count_nonzero(~np.isnan(self.task_arrivals)))

    def makespan(self, tasks: int, limit: float) -> float:
        """Last arrival after the start [s]; ``limit`` when any of ``tasks`` did not arrive."""
        if tasks == 0:
            return 0.0
        if self.success_count() < tasks:
            return limit
        return float(np.nanmax(self.task_arrivals) - self.t_start)

    def smoothness(self, trips: int) -> tuple[float, float]:
        """(stops, cusps) per trip: every robot's counts summed over ``trips`` tasks."""
        if trips <= 0:
            return (0.0, 0.0)
        return (float(self.stops.sum()) / trips, float(self.cusps.sum()) / trips)

    def path_ratio(self) -> float | None:
        """Mean over the tasks that arrived of the distance driven for the task / its
        straight line (None if none arrived)."""
        use = ~np.isnan(self.task_driven) & (np.nan_to_num(self.task_straight) > 1e-9)
        if not use.any():
            return None
        return float(np.mean(self.task_driven[use] / self.task_straight[use]))


class _Smoothness:
    """Running stop and cusp counts per robot (definitions in the module docstring)."""

    def __init__(self, n: int) -> None:
        self.stops = np.zeros(n, dtype=np.int64)
        self.cusps = np.zeros(n, dtype=np.int64)
        self._sign = np.zeros(n, dtype=np.int8)  # sign of u when last moving (0: not yet)
        self._still_since = np.full(n, np.nan)  # start of the current standstill [s]

    def add(
        self, t: float, dt: float, before: FloatArray, now: FloatArray, active: BoolArray
    ) -> None:
        """One tick: true poses ``before`` and ``now`` (N, 3) ``dt`` seconds apart; ``active``
        robots are on a trip at ``now`` (the others end theirs)."""
        self._sign[~active] = 0
        self._still_since[~active] = np.nan
        if dt <= 0.0 or not active.any():
            return
        dx, dy = now[:, 0] - before[:, 0], now[:, 1] - before[:, 1]
        u = (dx * np.cos(before[:, 2]) + dy * np.sin(before[:, 2])) / dt
        moving = active & (np.abs(u) >= MOVING_SPEED_M_S)
        sign = np.sign(u).astype(np.int8)
        started = self._sign != 0
        self.cusps += moving & started & (sign != self._sign)
        paused = t - self._still_since >= STOP_MIN_S - 1e-9  # NaN compares False
        self.stops += moving & started & paused
        self._still_since[moving] = np.nan
        self._sign[moving] = sign[moving]
        still = active & ~moving & started & np.isnan(self._still_since)
        self._still_since[still] = t - dt  # the standstill began at the previous tick


class RunMetrics:
    """Accumulates :class:`RunResult` figures from chunks of ticks (see the module docstring).

    ``radii`` [m] per robot; ``goals`` (N, 3) with NaN rows for robots without a task (a
    robot's last task: path ratio and deadlocks); ``tasks`` (robot index, goal x, goal y)
    per task, default one per row of ``goals``; ``obstacles`` the posts and wall segments
    (a hit: a body overlapping one's body); ``modes`` the trace's mode names; ticks outside
    [``t_start``, ``t_end``] are ignored; one tick in ``path_stride`` is kept.
    """

    def __init__(
        self,
        radii: Sequence[float],
        goals: FloatArray | Sequence[Sequence[float]],
        obstacles: Sequence[Obstacle],
        modes: Sequence[str],
        *,
        t_start: float = 0.0,
        t_end: float = math.inf,
        path_stride: int = 5,
        tasks: Sequence[tuple[int, float, float]] | None = None,
        arrival_radius_m: float = ARRIVAL_RADIUS_M,
    ) -> None:
        n = len(radii)
        self.t_start, self.t_end, self.path_stride = t_start, t_end, max(1, path_stride)
        self.goals = np.asarray(goals, dtype=np.float64).reshape(n, 3)
        if tasks is None:
            tasks = [(r, g[0], g[1]) for r, g in enumerate(self.goals) if not np.isnan(g[0])]
        self._task_robot = np.array([t[0] for t in tasks], dtype=np.intp)
        self._task_xy = np.array([t[1:] for t in tasks], dtype=np.float64).reshape(-1, 2)
        self._task_arrivals = np.full(len(tasks), np.nan)
        self._task_driven = np.full(len(tasks), np.nan)
        self._task_straight = np.full(len(tasks), np.nan)
        self._leg_driven = np.zeros(n)  # distance driven when the robot's leg began [m]
        self._leg_start: FloatArray | None = None  # (N, 2) where each robot's leg began
        self.arrival_radius_m = arrival_radius_m
        #: (K, 5): start x, y, body radius, end x, y [m] of every post and wall segment.
        self.obstacles = np.array(
            [(o.x, o.y, o.body_radius, *o.far_end) for o in obstacles], dtype=np.float64
        ).reshape(-1, 5)
        self._n = n
        self._pairs = np.triu_indices(n, k=1)
        self._radii = np.asarray(radii, dtype=np.float64)
        self._contact = (
            self._radii[self._pairs[0]] + self._radii[self._pairs[1]] - COLLISION_SLACK_M
        )
        codes = {name: k for k, name in enumerate(modes)}
        self._arrived = codes.get("arrived", -1)
        self._passive = [codes[m] for m in ("idle", "waiting", "arrived") if m in codes]
        self._passive.append(NO_MODE)
        self._off_trip = [codes[m] for m in ("idle", "arrived") if m in codes] + [NO_MODE]
        self._touching = np.zeros(len(self._contact), dtype=bool)
        self._touched = np.zeros(len(self._contact), dtype=bool)
        self._hit = np.zeros(n, dtype=bool)
        self._events: list[Event] = []
        self._min_sep = math.inf
        self._min_clear = math.inf
        self._arrivals = np.full(n, np.nan)
        self._driven = np.zeros(n)
        self._starts: FloatArray | None = None
        self._last: FloatArray | None = None
        self._best_d = np.full(n, np.nan)
        self._since = np.full(n, np.nan)  # time of the last progress (NaN: not active)
        self._deadlocked = np.zeros(n, dtype=bool)
        self._deadlocks: list[Event] = []
        self._path_t: list[float] = []
        self._paths: list[FloatArray] = []
        self._ticks = 0
        self._t_last = math.nan
        self._smooth = _Smoothness(n)

    def add(self, chunk: TraceChunk) -> None:
        """Fold in consecutive ticks (times ascending)."""
        keep = (chunk.t >= self.t_start) & (chunk.t <= self.t_end)
        if not keep.any():
            return
        t, poses, modes = chunk.t[keep], chunk.poses[keep], chunk.modes[keep]
        if self._starts is None:
            self._starts = poses[0].copy()
            self._leg_start = poses[0, :, :2].copy()
        self._distances(t, poses)
        self._motion(t, poses, modes)
        first = self._ticks
        self._ticks += len(t)
        self._t_last = float(t[-1])
        for k in range(len(t)):
            if (first + k) % self.path_stride == 0:
                self._path_t.append(float(t[k]))
                self._paths.append(poses[k].copy())

    def _distances(self, t: FloatArray, poses: FloatArray) -> None:
        i, j = self._pairs
        pairs, n_obs = len(i), self.obstacles.shape[0]
        step = max(1, _BLOCK // max(1, pairs + self._n * n_obs))
        for a in range(0, len(t), step):
            xy = poses[a : a + step, :, :2]
            if pairs:
                d = np.hypot(*(xy[:, i] - xy[:, j]).transpose(2, 0, 1))  # (T, M)
                self._min_sep = min(self._min_sep, float(d.min()))
                touching = d < self._contact
                previous = np.vstack([self._touching[None], touching[:-1]])
                for tick, pair in zip(*np.nonzero(touching & ~previous), strict=True):
                    if len(self._events) < MAX_EVENTS:
                        p, q = xy[tick, i[pair]], xy[tick, j[pair]]
                        self._events.append(
                            Event(float(t[a + tick]), (int(i[pair]), int(j[pair])),
                                  float(p[0] + q[0]) / 2, float(p[1] + q[1]) / 2)
                        )  # fmt: skip
                self._touched |= touching.any(axis=0)
                self._touching = touching[-1]
            if n_obs:
                core = segment_distances(xy, self.obstacles[:, :2], self.obstacles[:, 3:])
                clearance = core - self._radii[None, :, None] - self.obstacles[None, None, :, 2]
                self._min_clear = min(self._min_clear, float(clearance.min()))
                self._hit |= (clearance < -COLLISION_SLACK_M).any(axis=(0, 2))

    def _motion(self, t: FloatArray, poses: FloatArray, modes: ModeArray) -> None:
        before = poses[:1] if self._last is None else self._last[None]
        previous = np.concatenate([before, poses[:-1]])
        steps = np.hypot(*(poses[:, :, :2] - previous[:, :, :2]).transpose(2, 0, 1))  # (T, N)
        driven_at = self._driven[None, :] + np.cumsum(steps, axis=0)  # after each tick
        self._driven = driven_at[-1].copy()
        t_before = self._t_last if self._last is not None else float(t[0])
        self._last = poses[-1].copy()
        on_trip = ~np.isin(modes, self._off_trip)
        for k in range(len(t)):
            dt = float(t[k]) - (t_before if k == 0 else float(t[k - 1]))
            self._smooth.add(float(t[k]), dt, previous[k], poses[k], on_trip[k])
        arrived = modes == self._arrived
        newly = np.isnan(self._arrivals) & arrived.any(axis=0)
        if newly.any():
            arrival_tick = arrived.argmax(axis=0)
            self._arrivals[newly] = t[arrival_tick[newly]]
        waiting = np.nonzero(np.isnan(self._task_arrivals))[0]
        if waiting.size and arrived.any():
            robot, goal = self._task_robot[waiting], self._task_xy[waiting]
            near = np.hypot(poses[:, robot, 0] - goal[:, 0], poses[:, robot, 1] - goal[:, 1])
            there = arrived[:, robot] & (near <= self.arrival_radius_m)  # (T, waiting)
            done = there.any(axis=0)
            ticks = there.argmax(axis=0)
            self._task_arrivals[waiting[done]] = t[ticks[done]]
            for j in sorted(np.nonzero(done)[0], key=lambda j: int(ticks[j])):
                self._leg(int(waiting[j]), int(robot[j]), int(ticks[j]), driven_at, poses)
        goals = self.goals
        tasked = ~np.isnan(goals[:, 0])
        moving = ~np.isin(modes, self._passive) & tasked[None, :]
        for k in range(len(t)):
            p = poses[k]
            dist = np.hypot(goals[:, 0] - p[:, 0], goals[:, 1] - p[:, 1])
            watched = moving[k] & (dist > NEAR_GOAL_M)
            self._since[~watched] = np.nan
            if not watched.any():
                continue
            fresh = watched & np.isnan(self._since)
            better = watched & (dist < self._best_d - PROGRESS_M)
            self._best_d[fresh | better] = dist[fresh | better]
            self._since[fresh | better] = t[k]
            stuck = watched & ~self._deadlocked & (t[k] - self._since >= DEADLOCK_WINDOW_S)
            for r in np.nonzero(stuck)[0]:
                self._deadlocked[r] = True
                self._deadlocks.append(
                    Event(float(t[k]), (int(r),), float(p[r, 0]), float(p[r, 1]))
                )

    def _leg(
        self, task: int, robot: int, tick: int, driven_at: FloatArray, poses: FloatArray
    ) -> None:
        """Task ``task`` arrived at ``tick``: its leg's distance and straight line; the
        robot's next leg begins here."""
        assert self._leg_start is not None
        self._task_driven[task] = driven_at[tick, robot] - self._leg_driven[robot]
        self._task_straight[task] = math.dist(self._leg_start[robot], self._task_xy[task])
        self._leg_driven[robot] = driven_at[tick, robot]
        self._leg_start[robot] = poses[tick, robot, :2]

    def result(self) -> RunResult:
        n = self._n
        empty = np.full((n, 3), np.nan)
        return RunResult(
            ticks=self._ticks,
            t_start=self.t_start,
            t_last=self._t_last,
            collision_pairs=int(np.count_nonzero(self._touched)),
            collisions=list(self._events),
            min_separation_m=None if math.isinf(self._min_sep) else self._min_sep,
            obstacle_hits=int(np.count_nonzero(self._hit)),
            min_obstacle_clearance_m=None if math.isinf(self._min_clear) else self._min_clear,
            arrivals=self._arrivals.copy(),
            driven=self._driven.copy(),
            starts=empty if self._starts is None else self._starts,
            goals=self.goals,
            deadlocks=list(self._deadlocks),
            path_t=np.asarray(self._path_t),
            paths=np.asarray(self._paths).reshape(-1, n, 3),
            final=empty if self._last is None else self._last,
            task_arrivals=self._task_arrivals.copy(),
            task_driven=self._task_driven.copy(),
            task_straight=self._task_straight.copy(),
            stops=self._smooth.stops.copy(),
            cusps=self._smooth.cusps.copy(),
        )
