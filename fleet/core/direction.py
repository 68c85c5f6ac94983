"""Direction choice for ``auto`` tasks: cw (law 20) or ccw (law 17) per robot (pure).

**Superseded by** :mod:`fleet.core.planner` (laws *and* start delays and holds, clusters,
corridors). Kept only while ``fleet.service`` still calls :func:`choose_directions`;
delete it, with ``tests/fleet/core/test_direction.py``, once the service calls
:func:`fleet.core.planner.plan`.

A candidate choice is scored by a closed-loop rollout of the whole fleet with the batch
simulator (``fleet.core.simulate``, the same control code the robots run):

* every moving robot from its current pose to its goal with its law and gains;
* peers as moving obstacles through the Eq. (27) repulsion (influence radius
  ``Avoidance.peer_radius``, gain ``Avoidance.k_avoid``);
* static obstacles with their own influence radius, Eq. (27);
* standing robots (parked, idle, holding, lost) as rows that are done from the start: they
  stand still and repel like peers.

**Accuracy.** The rollout step ``dt`` should be the robots' control period (the agents run
forward Euler at 50 Hz, ``dt = 0.02`` s, the default here): at 0.05 s the repulsion acts
on coarser steps and close passes come out centimetres off, enough to call an unsafe
choice safe or the reverse. Optionally (``screen_dt``, off by default) the search
*screens* candidates at a coarser step (e.g. ``SCREEN_DT`` = 0.05 s, 2.5x fewer steps),
optimistically (a separation ``SCREEN_MARGIN`` smaller, so near misses of the coarse step
stay in the running), then *verifies* at ``dt`` with the real separation: the screened best
and its runners-up by cost (``VERIFIED`` in all, one batch) are rolled out again at ``dt``
and the best of those safe at ``dt`` is chosen (one whose robots all arrive within the
horizon first); if none is safe, the whole search runs again at ``dt``. Either way a
chosen choice has been judged at ``dt``.

``Scene.lead_time`` [s] is how long the plan takes to reach the robots (planning +
delivery): the robots already under way are first rolled on with the laws they run now
for that long (new robots stand still meanwhile), and every candidate starts from those
extrapolated poses; the separation over that lead-in counts too.

**Horizon** (adaptive, bounded). A rollout runs until every robot arrives or the horizon
passes. The horizon covers the predicted arrivals: ``horizon_factor`` times the slowest
robot's solo arrival time (one rollout without peers), at least ``min_horizon`` and at most
``max_horizon``; once a safe choice that finishes is known, later rollouts stop at
``horizon_factor`` times its makespan (a slower choice cannot win). So a choice that is
chosen has been judged over its whole run, not a prefix of it.

**Cost** (lexicographic, smaller is better):

1. safety: a choice is *safe* when every pair involving a moving robot keeps a centre
   distance of at least ``separation`` [m] (or, for a pair that starts closer, does not get
   closer than it started). Unsafe choices rank after safe ones, by how far the worst pair
   falls short;
2. makespan [s]: the latest predicted arrival among the moving robots (an unfinished robot
   counts ``horizon + remaining distance / top speed``);
3. the sum of the predicted arrival times [s].

**Search.** Robots whose task asks for ``cw``/``ccw`` are fixed. New ``auto`` robots are
searched exhaustively (2^k rollouts) when k <= ``exhaustive_limit``, otherwise by a bounded
local search: the uniform choices (all ccw, all cw) seed a best-improvement descent over
single flips, within ``budget`` rollouts. Robots already under way keep their law unless the
best choice keeping them is unsafe *and* flipping some of them is strictly safer (second
phase, same bounds); the caller then sends those robots a higher ``revision`` of their task
(``fleet.core.wire``). Candidates are rolled out several at a time in one simulator batch, each
in its own copy of the scene placed far from the others (beyond every influence radius, so
copies never interact) and simulated as independent groups (``simulate(group=...)``: peer
terms only within a copy), so a batch step costs a small multiple of one copy's step.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from fleet.core.params import Avoidance, Gains, RobotProfile, Tolerance
from fleet.core.simulate import BatchProblem, simulate
from fleet.core.types import LAWS, BoolArray, FloatArray, Law, Posture
from fleet.core.wire import Obstacle

ROLLOUT_DT = 0.02  # [s] the agents' control period at 50 Hz
#: [s] a step for the optional screening search (verified at ROLLOUT_DT). Off by default:
#: on the bench's random yard (seed 2) its choice was safe but much slower in the real run.
SCREEN_DT = 0.05
#: Screened choices verified at the fine step (the best and its runners-up, one batch).
VERIFIED = 4
#: [m] the screening counts a choice safe down to ``separation - SCREEN_MARGIN`` (the
#: coarse step's error on close passes is centimetres); verification uses ``separation``.
SCREEN_MARGIN = 0.05
MIN_HORIZON = 60.0  # [s]
MAX_HORIZON = 300.0  # [s]
HORIZON_FACTOR = 2.0
#: Robots per simulator batch when several candidates are rolled out together.
BATCH_ROBOTS = 80
_DEFAULT_AVOIDANCE = Avoidance()
_DEFAULT_PROFILE = RobotProfile()
_STANDING_TOL = Tolerance(position=1e-3, heading=1e-3)


@dataclass(frozen=True)
class Mover:
    """A robot that is (or is about to be) driving to a goal.

    ``law`` is the law it drives with now (None for a robot not yet under way);
    ``auto`` says whether the fleet may choose (False: the task fixed ``law``).
    """

    robot_id: str
    pose: Posture
    goal: Posture
    gains: dict[Law, Gains]
    tolerance: Tolerance
    law: Law | None = None
    auto: bool = True


@dataclass(frozen=True)
class Scene:
    """Everything a rollout needs besides the choice of laws."""

    movers: Sequence[Mover]
    standing: Sequence[tuple[float, float]] = ()  # positions of robots standing still [m]
    obstacles: Sequence[Obstacle] = ()
    avoidance: Avoidance = _DEFAULT_AVOIDANCE
    profile: RobotProfile = _DEFAULT_PROFILE
    lead_time: float = 0.0  # [s] until the plan reaches the robots (see module docstring)


@dataclass(frozen=True)
class Outcome:
    """Score of one choice of laws (see the module docstring for the cost)."""

    laws: tuple[Law, ...]  # one per mover
    safe: bool
    shortfall: float  # [m] how far the worst pair falls below its allowed distance (>= 0)
    min_separation: float  # [m] closest centre distance of a pair involving a mover
    makespan: float  # [s]
    total_time: float  # [s]
    done: bool  # every mover arrived within the horizon

    @property
    def key(self) -> tuple[float, float, float]:
        if self.safe:
            return (0.0, self.makespan, self.total_time)
        return (1.0 + self.shortfall, self.makespan, self.total_time)

    @property
    def safety_key(self) -> tuple[bool, float]:
        """Smaller is safer: unsafe after safe, then by shortfall."""
        return (not self.safe, self.shortfall)


@dataclass
class DirectionChoice:
    """The chosen laws and how they were found."""

    best: Outcome
    evaluations: int
    searched: list[str] = field(default_factory=list)

    horizon: float = 0.0  # [s] horizon of the last rollouts

    def laws_by_robot(self, scene: Scene) -> dict[str, Law]:
        return {m.robot_id: law for m, law in zip(scene.movers, self.best.laws, strict=True)}

    def flipped(self, scene: Scene) -> list[str]:
        """Robots already under way whose chosen law differs from the one they run."""
        return [
            m.robot_id
            for m, law in zip(scene.movers, self.best.laws, strict=True)
            if m.law is not None and m.law != law
        ]


_Rollout = tuple[FloatArray, BoolArray, FloatArray, FloatArray]  # min_pair, done, time, pose


@dataclass(frozen=True)
class _Lead:
    """The lead-in rollout: poses after ``Scene.lead_time`` and the separation meanwhile."""

    poses: list[Posture]  # one per mover
    min_pair: FloatArray  # (G, G) over the lead-in, G = movers + standing


def _rows(scene: Scene, poses: Sequence[Posture] | None = None) -> tuple[FloatArray, FloatArray]:
    """Start and goal rows of one copy of the scene: movers, then standing robots."""
    movers = list(scene.movers)
    stand = [(x, y, 0.0) for x, y in scene.standing]
    start = np.array(
        [tuple(p) for p in (poses or [m.pose for m in movers])] + stand, dtype=np.float64
    ).reshape(-1, 3)
    goal = np.array([m.goal for m in movers] + stand, dtype=np.float64).reshape(-1, 3)
    return start, goal


def _spacing(scene: Scene) -> float:
    """Distance between copies of the scene in one batch [m]: beyond every interaction."""
    start, goal = _rows(scene)
    pts = [start[:, :2], goal[:, :2]]
    if scene.obstacles:
        pts.append(np.array([(o.x, o.y) for o in scene.obstacles]))
    allp = np.concatenate(pts)
    extent = float(np.ptp(allp, axis=0).max()) if allp.size else 0.0
    reach = max([scene.avoidance.peer_radius] + [o.radius for o in scene.obstacles])
    return 4.0 * extent + 4.0 * reach + 100.0  # robots wander a little beyond start/goal


def _rollout_batch(
    scene: Scene,
    candidates: Sequence[Sequence[Law]],
    dt: float,
    horizon: float,
    poses: Sequence[Posture] | None = None,
    standing_movers: bool = False,
) -> list[_Rollout]:
    """Roll out several choices of laws in one batch; per candidate (min_pair, done, time,
    final_pose) of its own copy of the scene. ``standing_movers``: movers not under way
    (``law`` None) stand still (the lead-in)."""
    movers = list(scene.movers)
    n_m, n_s = len(movers), len(scene.standing)
    g = n_m + n_s
    start1, goal1 = _rows(scene, poses)
    if standing_movers:
        for i, m in enumerate(movers):
            if m.law is None:
                goal1[i] = start1[i]
    k = len(candidates)
    offset = np.zeros((k * g, 3))
    spacing = _spacing(scene)
    offset[:, 0] = np.repeat(np.arange(k) * spacing, g)
    start = np.tile(start1, (k, 1)) + offset
    goal = np.tile(goal1, (k, 1)) + offset
    spare = next(iter(movers[0].gains.values()))
    gains: list[Gains] = []
    laws: list[Law] = []
    tolerance: list[Tolerance] = []
    for cand in candidates:
        for m, law in zip(movers, cand, strict=True):
            gains.append(m.gains[law])
            laws.append(law)
            still = standing_movers and m.law is None
            tolerance.append(_STANDING_TOL if still else m.tolerance)
        gains += [spare] * n_s
        laws += ["ccw"] * n_s
        tolerance += [_STANDING_TOL] * n_s
    obstacles = [(o.x + j * spacing, o.y) for j in range(k) for o in scene.obstacles]
    problem = BatchProblem.build(
        start,
        goal,
        gains,
        laws,
        tolerance=tolerance,
        profile=scene.profile,
        obstacles=obstacles,
        obstacle_radius=[o.radius for _ in range(k) for o in scene.obstacles],
        k_avoid=scene.avoidance.k_avoid,
        peer_radius=scene.avoidance.peer_radius,
        min_x_oa=scene.avoidance.min_x_oa,
    )
    result = simulate(problem, dt=dt, max_time=horizon, track_separation=True, group=g)
    assert result.min_pair_distance is not None
    out = []
    for j in range(k):
        s = slice(j * g, (j + 1) * g)
        fp = result.final_pose[s].copy()
        fp[:, 0] -= j * spacing
        out.append((result.min_pair_distance[s, s], result.done[s], result.time[s], fp))
    return out


def _lead_in(scene: Scene, dt: float) -> _Lead | None:
    """Roll the robots under way on with their current laws for ``scene.lead_time``."""
    movers = list(scene.movers)
    if scene.lead_time <= 0 or not any(m.law is not None for m in movers):
        return None
    laws = [m.law or "ccw" for m in movers]
    ((min_pair, _, _, final),) = _rollout_batch(
        scene, [laws], dt, scene.lead_time, standing_movers=True
    )
    poses = [tuple(float(v) for v in final[i]) for i in range(len(movers))]
    return _Lead(poses=[(p[0], p[1], p[2]) for p in poses], min_pair=min_pair)


def _score(
    scene: Scene,
    laws: Sequence[Law],
    separation: float,
    horizon: float,
    rollout: _Rollout,
    lead: _Lead | None,
) -> Outcome:
    min_pair, done_all, time_all, final = rollout
    n_m = len(scene.movers)
    start, goal = _rows(scene)
    if lead is not None:
        min_pair = np.minimum(min_pair, lead.min_pair)
    d0 = np.hypot(start[:, None, 0] - start[None, :, 0], start[:, None, 1] - start[None, :, 1])
    allowed = np.minimum(separation, d0 - 1e-9)
    involved = np.zeros_like(d0, dtype=bool)
    involved[:n_m, :] = True
    involved[:, :n_m] = True
    np.fill_diagonal(involved, False)
    if involved.any():
        shortfall = float(np.max(np.where(involved, allowed - min_pair, -np.inf)))
        min_sep = float(np.min(np.where(involved, min_pair, np.inf)))
    else:
        shortfall, min_sep = -np.inf, float("inf")
    top_speed = scene.profile.max_speed if np.isfinite(scene.profile.max_speed) else 1.0
    remaining = np.hypot(final[:n_m, 0] - goal[:n_m, 0], final[:n_m, 1] - goal[:n_m, 1])
    done = done_all[:n_m]
    times = np.where(done, time_all[:n_m], horizon + remaining / top_speed)
    if lead is not None:
        times = times + scene.lead_time
    return Outcome(
        laws=tuple(laws),
        safe=shortfall <= 0.0,
        shortfall=max(shortfall, 0.0),
        min_separation=min_sep,
        makespan=float(times.max()),
        total_time=float(times.sum()),
        done=bool(done.all()),
    )


def evaluate_many(
    scene: Scene,
    candidates: Sequence[Sequence[Law]],
    separation: float,
    dt: float = ROLLOUT_DT,
    horizon: float = MIN_HORIZON,
    lead: _Lead | None = None,
) -> list[Outcome]:
    """Roll out the fleet once per choice of ``laws`` (one per mover) and score each.

    Candidates share simulator batches of about ``BATCH_ROBOTS`` robots (see the module
    docstring); ``lead`` is the lead-in (``Scene.lead_time``), computed if not given.
    """
    movers = list(scene.movers)
    n_m = len(movers)
    for laws in candidates:
        if len(laws) != n_m:
            raise ValueError("one law per mover")
    if n_m == 0:
        return [Outcome((), True, 0.0, float("inf"), 0.0, 0.0, True) for _ in candidates]
    if lead is None:
        lead = _lead_in(scene, dt)
    poses = lead.poses if lead is not None else None
    per_batch = max(1, BATCH_ROBOTS // (n_m + len(scene.standing)))
    out: list[Outcome] = []
    for i in range(0, len(candidates), per_batch):
        chunk = candidates[i : i + per_batch]
        for laws, rollout in zip(
            chunk, _rollout_batch(scene, chunk, dt, horizon, poses), strict=True
        ):
            out.append(_score(scene, laws, separation, horizon, rollout, lead))
    return out


def evaluate(
    scene: Scene,
    laws: Sequence[Law],
    separation: float,
    dt: float = ROLLOUT_DT,
    horizon: float = MIN_HORIZON,
) -> Outcome:
    """Roll out the fleet with ``laws`` (one per mover) and score it."""
    return evaluate_many(scene, [laws], separation, dt, horizon)[0]


def solo_horizon(
    scene: Scene,
    dt: float = ROLLOUT_DT,
    factor: float = HORIZON_FACTOR,
    min_horizon: float = MIN_HORIZON,
    max_horizon: float = MAX_HORIZON,
) -> float:
    """Horizon [s] covering the predicted arrivals: ``factor`` x the slowest solo arrival
    (each mover alone, its current law or the faster one, no peers), bounded."""
    movers = list(scene.movers)
    if not movers:
        return min_horizon
    start, goal = _rows(scene)
    rows, laws, gains, tol = [], [], [], []
    for i, m in enumerate(movers):
        for law in (m.law,) if m.law is not None else LAWS:
            rows.append(i)
            laws.append(law)
            gains.append(m.gains[law])
            tol.append(m.tolerance)
    problem = BatchProblem.build(
        start[rows],
        goal[rows],
        gains,
        laws,
        tolerance=tol,
        profile=scene.profile,
        obstacles=[(o.x, o.y) for o in scene.obstacles],
        obstacle_radius=[o.radius for o in scene.obstacles],
        k_avoid=scene.avoidance.k_avoid,
        min_x_oa=scene.avoidance.min_x_oa,
    )
    result = simulate(problem, dt=max(dt, 0.05), max_time=max_horizon)
    best = np.full(len(movers), max_horizon)
    for r, i in enumerate(rows):
        if result.done[r]:
            best[i] = min(best[i], float(result.time[r]))
    return float(np.clip(factor * best.max() + scene.lead_time, min_horizon, max_horizon))


class _Search:
    """Memoised evaluations within a budget of rollouts; adapts the horizon (docstring)."""

    def __init__(
        self, scene: Scene, separation: float, dt: float, horizon: float, factor: float
    ) -> None:
        self.scene, self.separation, self.dt = scene, separation, dt
        self.horizon, self.max_horizon, self.factor = horizon, horizon, factor
        self.cache: dict[tuple[Law, ...], Outcome] = {}
        self.lead = _lead_in(scene, dt)

    def many(self, candidates: Sequence[Sequence[Law]]) -> list[Outcome]:
        todo = list(dict.fromkeys(tuple(c) for c in candidates if tuple(c) not in self.cache))
        if todo:
            outs = evaluate_many(
                self.scene, todo, self.separation, self.dt, self.horizon, self.lead
            )
            for key, out in zip(todo, outs, strict=True):
                self.cache[key] = out
                if out.safe and out.done:  # a slower choice cannot beat this one
                    limit = self.factor * out.makespan
                    self.horizon = min(self.horizon, max(limit, MIN_HORIZON))
        return [self.cache[tuple(c)] for c in candidates]

    def __call__(self, laws: Sequence[Law]) -> Outcome:
        return self.many([laws])[0]


def _flip(law: Law) -> Law:
    return "cw" if law == "ccw" else "ccw"


def _search(
    run: _Search,
    base: tuple[Law, ...],
    free: Sequence[int],
    exhaustive_limit: int,
    budget: int,
    rank: Callable[[Outcome], tuple[float, float, float]],
) -> Outcome:
    """Best choice by ``rank`` over the ``free`` indices of ``base`` (exhaustive or local)."""
    if not free:
        return run(base)
    if len(free) <= exhaustive_limit:
        combos = []
        for combo in itertools.product(LAWS, repeat=len(free)):
            laws = list(base)
            for i, law in zip(free, combo, strict=True):
                laws[i] = law
            combos.append(laws)
        return min([run(base), *run.many(combos)], key=rank)  # ties: the earliest
    seeds = [list(base)]
    for uniform in LAWS:
        laws = list(base)
        for i in free:
            laws[i] = uniform
        seeds.append(laws)
    best = min(run.many(seeds), key=rank)
    start = len(run.cache)
    while len(run.cache) - start < budget:
        flips = []
        for i in free:
            laws = list(best.laws)
            laws[i] = _flip(laws[i])
            if tuple(laws) not in run.cache:
                flips.append(laws)
        flips = flips[: budget - (len(run.cache) - start)]
        if not flips:
            break
        candidate = min(run.many(flips), key=rank)
        if not rank(candidate) < rank(best):
            break
        best = candidate
    return best


def _by_cost(out: Outcome) -> tuple[float, float, float]:
    return out.key


def _by_safety(out: Outcome) -> tuple[float, float, float]:
    return (float(not out.safe), out.shortfall, out.makespan)


def _choose(
    scene: Scene,
    separation: float,
    dt: float,
    horizon: float,
    exhaustive_limit: int,
    budget: int,
    horizon_factor: float,
) -> tuple[DirectionChoice, _Search]:
    """The search of the module docstring at one step ``dt``."""
    movers = list(scene.movers)
    base: tuple[Law, ...] = tuple(m.law or "ccw" for m in movers)
    new = [i for i, m in enumerate(movers) if m.auto and m.law is None]
    under_way = [i for i, m in enumerate(movers) if m.auto and m.law is not None]
    run = _Search(scene, separation, dt, horizon, horizon_factor)
    best = _search(run, base, new, exhaustive_limit, budget, _by_cost)
    searched = [f"new robots: {len(new)}"]
    if not best.safe and under_way:
        # Second phase: flip robots already under way only if that is strictly safer.
        safer = _search(run, best.laws, under_way, exhaustive_limit, budget, _by_safety)
        searched.append(f"under way: {len(under_way)}")
        if safer.safety_key < best.safety_key:
            best = safer
    decision = DirectionChoice(
        best=best, evaluations=len(run.cache), searched=searched, horizon=run.horizon
    )
    return decision, run


def choose_directions(
    scene: Scene,
    separation: float,
    dt: float = ROLLOUT_DT,
    horizon: float | None = None,
    exhaustive_limit: int = 4,
    budget: int = 24,
    horizon_factor: float = HORIZON_FACTOR,
    screen_dt: float | None = None,
) -> DirectionChoice:
    """Choose a law for every mover (see the module docstring for cost and search).

    ``horizon`` [s]: None (default) adapts it to the predicted arrivals
    (:func:`solo_horizon`); a number fixes the longest rollout. ``screen_dt`` [s]: step
    of the screening search, verified at ``dt`` (None, or not above ``dt``: search at
    ``dt`` only).
    """
    movers = list(scene.movers)
    for m in movers:
        if not m.auto and m.law is None:
            raise ValueError(f"mover {m.robot_id}: a fixed direction needs its law")
    if horizon is None:
        horizon = solo_horizon(scene, dt, horizon_factor)
    if screen_dt is None or screen_dt <= dt or not movers:
        return _choose(scene, separation, dt, horizon, exhaustive_limit, budget, horizon_factor)[0]
    optimistic = max(separation - SCREEN_MARGIN, 0.0)
    coarse, run = _choose(
        scene, optimistic, screen_dt, horizon, exhaustive_limit, budget, horizon_factor
    )
    best = coarse.best
    # Runners-up: the next screened choices by the same cost (safe ones first, then by
    # shortfall: close calls at screen_dt may be safe at dt); they may flip a robot under
    # way only if the screened best does (flips need to be strictly safer).
    keeps = [i for i, m in enumerate(movers) if m.law is not None and best.laws[i] == m.law]
    others = sorted(
        (
            o
            for o in run.cache.values()
            if o.laws != best.laws and all(o.laws[i] == movers[i].law for i in keeps)
        ),
        key=_by_cost,
    )
    candidates = [best.laws] + [o.laws for o in others[: VERIFIED - 1]]
    verified = evaluate_many(scene, candidates, separation, dt, horizon)
    safe = [o for o in verified if o.safe]
    searched = [*coarse.searched, f"screened at dt={screen_dt:g} s"]
    if safe:
        return DirectionChoice(
            best=min(safe, key=lambda o: (not o.done, *_by_cost(o))),
            evaluations=coarse.evaluations + len(verified),
            searched=[*searched, f"verified at dt={dt:g} s"],
            horizon=horizon,
        )
    fine, _ = _choose(scene, separation, dt, horizon, exhaustive_limit, budget, horizon_factor)
    return DirectionChoice(
        best=fine.best,
        evaluations=coarse.evaluations + len(verified) + fine.evaluations,
        searched=[*searched, "not safe at dt: searched again", *fine.searched],
        horizon=fine.horizon,
    )
