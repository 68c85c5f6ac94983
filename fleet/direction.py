"""Direction choice for ``auto`` tasks: cw (law 20) or ccw (law 17) per robot (pure).

A candidate choice is scored by a closed-loop rollout of the whole fleet with the batch
simulator (``fleet.simulate``, the same control code the robots run):

* every moving robot from its current pose to its goal with its law and gains;
* peers as moving obstacles through the Eq. (27) repulsion (influence radius
  ``Avoidance.peer_radius``, gain ``Avoidance.k_avoid``);
* static obstacles with their own influence radius, Eq. (27);
* standing robots (parked, idle, holding, lost) as rows that are done from the start: they
  stand still and repel like peers.

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
local search: the uniform choices (all ccw, all cw) seed a coordinate descent of single
flips, within ``budget`` rollouts. Robots already under way keep their law unless the best
choice keeping them is unsafe *and* flipping some of them is strictly safer (second phase,
same bounds).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from fleet.control import LAWS, Law
from fleet.params import Avoidance, Gains, RobotProfile, Tolerance
from fleet.simulate import BatchProblem, simulate
from fleet.wire import Obstacle

Posture = tuple[float, float, float]

ROLLOUT_DT = 0.05  # [s]
ROLLOUT_HORIZON = 60.0  # [s]
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
class Decision:
    """The chosen laws and how they were found."""

    best: Outcome
    evaluations: int
    searched: list[str] = field(default_factory=list)

    def laws_by_robot(self, scene: Scene) -> dict[str, Law]:
        return {m.robot_id: law for m, law in zip(scene.movers, self.best.laws, strict=True)}


def evaluate(
    scene: Scene,
    laws: Sequence[Law],
    separation: float,
    dt: float = ROLLOUT_DT,
    horizon: float = ROLLOUT_HORIZON,
) -> Outcome:
    """Roll out the fleet with ``laws`` (one per mover) and score it."""
    movers = list(scene.movers)
    n_m = len(movers)
    if len(laws) != n_m:
        raise ValueError("one law per mover")
    if n_m == 0:
        return Outcome((), True, 0.0, float("inf"), 0.0, 0.0, True)
    stand = [(x, y, 0.0) for x, y in scene.standing]
    start = np.array([m.pose for m in movers] + stand, dtype=np.float64)
    goal = np.array([m.goal for m in movers] + stand, dtype=np.float64)
    gains = [m.gains[law] for m, law in zip(movers, laws, strict=True)]
    gains += [next(iter(movers[0].gains.values()))] * len(stand)
    problem = BatchProblem.build(
        start,
        goal,
        gains,
        list(laws) + ["ccw"] * len(stand),
        tolerance=[m.tolerance for m in movers] + [_STANDING_TOL] * len(stand),
        profile=scene.profile,
        obstacles=[(o.x, o.y) for o in scene.obstacles],
        obstacle_radius=[o.radius for o in scene.obstacles],
        k_avoid=scene.avoidance.k_avoid,
        peer_radius=scene.avoidance.peer_radius,
        min_x_oa=scene.avoidance.min_x_oa,
    )
    result = simulate(problem, dt=dt, max_time=horizon, track_separation=True)
    assert result.min_pair_distance is not None
    d0 = np.hypot(start[:, None, 0] - start[None, :, 0], start[:, None, 1] - start[None, :, 1])
    allowed = np.minimum(separation, d0 - 1e-9)
    involved = np.zeros_like(d0, dtype=bool)
    involved[:n_m, :] = True
    involved[:, :n_m] = True
    np.fill_diagonal(involved, False)
    if involved.any():
        shortfall = float(np.max(np.where(involved, allowed - result.min_pair_distance, -np.inf)))
        min_sep = float(np.min(np.where(involved, result.min_pair_distance, np.inf)))
    else:
        shortfall, min_sep = -np.inf, float("inf")
    top_speed = scene.profile.max_speed if np.isfinite(scene.profile.max_speed) else 1.0
    remaining = np.hypot(
        result.final_pose[:n_m, 0] - goal[:n_m, 0], result.final_pose[:n_m, 1] - goal[:n_m, 1]
    )
    times = np.where(result.done[:n_m], result.time[:n_m], horizon + remaining / top_speed)
    return Outcome(
        laws=tuple(laws),
        safe=shortfall <= 0.0,
        shortfall=max(shortfall, 0.0),
        min_separation=min_sep,
        makespan=float(times.max()),
        total_time=float(times.sum()),
        done=bool(result.done[:n_m].all()),
    )


class _Search:
    """Memoised evaluations within a budget of rollouts."""

    def __init__(self, scene: Scene, separation: float, dt: float, horizon: float) -> None:
        self.scene, self.separation, self.dt, self.horizon = scene, separation, dt, horizon
        self.cache: dict[tuple[Law, ...], Outcome] = {}

    def __call__(self, laws: Sequence[Law]) -> Outcome:
        key = tuple(laws)
        if key not in self.cache:
            self.cache[key] = evaluate(self.scene, key, self.separation, self.dt, self.horizon)
        return self.cache[key]


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
    best = run(base)
    if not free:
        return best
    if len(free) <= exhaustive_limit:
        for combo in itertools.product(LAWS, repeat=len(free)):
            laws = list(base)
            for i, law in zip(free, combo, strict=True):
                laws[i] = law
            out = run(laws)
            if rank(out) < rank(best):
                best = out
        return best
    start = len(run.cache)
    for uniform in LAWS:
        laws = list(base)
        for i in free:
            laws[i] = uniform
        out = run(laws)
        if rank(out) < rank(best):
            best = out
    improved = True
    while improved and len(run.cache) - start < budget:
        improved = False
        for i in free:
            if len(run.cache) - start >= budget:
                break
            laws = list(best.laws)
            laws[i] = _flip(laws[i])
            out = run(laws)
            if rank(out) < rank(best):
                best, improved = out, True
    return best


def _by_cost(out: Outcome) -> tuple[float, float, float]:
    return out.key


def _by_safety(out: Outcome) -> tuple[float, float, float]:
    return (float(not out.safe), out.shortfall, out.makespan)


def choose_directions(
    scene: Scene,
    separation: float,
    dt: float = ROLLOUT_DT,
    horizon: float = ROLLOUT_HORIZON,
    exhaustive_limit: int = 4,
    budget: int = 24,
) -> Decision:
    """Choose a law for every mover (see the module docstring for cost and search)."""
    movers = list(scene.movers)
    for m in movers:
        if not m.auto and m.law is None:
            raise ValueError(f"mover {m.robot_id}: a fixed direction needs its law")
    base: tuple[Law, ...] = tuple(m.law or "ccw" for m in movers)
    new = [i for i, m in enumerate(movers) if m.auto and m.law is None]
    under_way = [i for i, m in enumerate(movers) if m.auto and m.law is not None]
    run = _Search(scene, separation, dt, horizon)
    best = _search(run, base, new, exhaustive_limit, budget, _by_cost)
    searched = [f"new robots: {len(new)}"]
    if not best.safe and under_way:
        # Second phase: flip robots already under way only if that is strictly safer.
        safer = _search(run, best.laws, under_way, exhaustive_limit, budget, _by_safety)
        searched.append(f"under way: {len(under_way)}")
        if safer.safety_key < best.safety_key:
            best = safer
    return Decision(best=best, evaluations=len(run.cache), searched=searched)
