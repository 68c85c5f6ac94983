"""Gains found by search instead of trial and error (``parkfleet tune``).

The paper chose every gain "by trial and error" (Section 4). Here a search library does it:
scipy's differential evolution over log10 of (kx, ky, ktheta), every generation scored in
**one** call of the batch simulator (:func:`fleet.core.simulate.simulate`): the candidates of
a generation times the trips of the target are rows of one batch.

A *target* is what a candidate is scored on:

* a paper case (``first``, ``I``, ``II``, ``III``, ``parking``): its start, goal and
  tolerance at the paper's dt = 0.01 s;
* ``yard``: random start/goal postures of typical yard trips (:func:`yard_trips`, the
  fleet benchmark's 10 m x 10 m yard, random headings), the fleet's tolerance
  (0.1 m / 0.1 rad) at the agents' control period dt = 0.02 s, *time first*, every whole
  turn (revolution) priced at 2 s.

Every target drives the robot of :class:`~fleet.core.params.RobotProfile` (Table 10
geometry, 20 rad/s wheels): the wheel limit is enforced the way the robots enforce it,
scaling u and omega together (the path is kept, the speed drops), so no scored run ever
commands a wheel above the limit. Effort (Eq. 25) and distance are properties of the path,
so they barely change under that scaling; time does.

Cost of a candidate (smaller is better): the weighted sum of the mean effort (Eq. 25),
mean distance [m], mean time [s] and mean turns [revolutions] over the trips, plus
:data:`FAIL_PENALTY` times the fraction of trips that miss the tolerance within
``max_time``. *Turns* are the robot's whole rotation on a trip: a law turns one way only
(omega >= 0 for (17), <= 0 for (20); the wheel limit scales omega, never flips it), so it
is |theta_end - theta_start| / 2pi of the unwrapped heading. A trip needs less than one;
with a strong y_e^2 term (the time-first yard gains) the laws spin whole turns on the way
and drive between them (docs/paper.md), which the turns weight prices.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from fleet.core.params import Gains, RobotProfile, Tolerance
from fleet.core.simulate import PAPER_DT, BatchProblem, simulate
from fleet.core.types import LAWS, FloatArray, Law
from fleet.paper.scenarios import SCENARIOS, CaseName

#: Cost added per unit fraction of trips that do not reach the tolerance.
FAIL_PENALTY = 1000.0
#: Agents' control period [s] (50 Hz), the step of the yard target.
YARD_DT = 0.02
#: The fleet's default arrival tolerance (``TaskRequest``), used by the yard target.
YARD_TOLERANCE = Tolerance(position=0.1, heading=0.1)
#: Largest kx [1/s] of the yard search per law: Table 1's (the previous defaults). The
#: repulsion of Eq. (27) is added to u = kx x_e, so where two robots come to a standstill
#: facing each other depends on kx (and K_avoid) only: capping kx keeps those standoffs, and
#: the planner's safety margins tuned on them; above it the direction planner found unsafe
#: choices in most random 10-robot yards (docs/paper.md).
YARD_MAX_KX: dict[Law, float] = {law: SCENARIOS["first"].gains[law].kx for law in LAWS}
#: Longest run [s] of a case target (the paper's first scenario under the wheel limit
#: takes 73 s with Table 1's ccw gains).
MAX_CASE_TIME = 300.0
#: Search range of every gain (log10 is searched).
GAIN_RANGE = (0.1, 1000.0)


@dataclass(frozen=True)
class Weights:
    """Weights of the cost: effort (Eq. 25), distance [1/m], time [1/s] and turns
    [1/revolution]."""

    effort: float = 1.0
    distance: float = 1.0
    time: float = 0.0
    turns: float = 0.0

    def __post_init__(self) -> None:
        values = (self.effort, self.distance, self.time, self.turns)
        if not all(math.isfinite(v) and v >= 0 for v in values) or not any(values):
            raise ValueError("weights must be finite, >= 0 and not all zero")


#: Per-case default: the paper's own criteria ("short traveled distance and low control
#: effort", Section 4), time as a tie-break.
CASE_WEIGHTS = Weights(effort=1.0, distance=1.0, time=0.01)
#: Yard default: time first, every whole turn priced at 2 s (the laws spin whole turns on
#: the way with a strong y_e^2 term; a fleet of such robots stops and turns), distance as
#: a tie-break.
YARD_WEIGHTS = Weights(effort=0.0, distance=0.05, time=1.0, turns=2.0)


@dataclass(frozen=True)
class TuneTarget:
    """What a candidate is scored on: M trips, one law, tolerance, robot, step, weights."""

    name: str
    law: Law
    starts: FloatArray  # (M, 3) world-frame postures [m, m, rad]
    goals: FloatArray  # (M, 3)
    tolerance: Tolerance
    profile: RobotProfile
    dt: float  # [s]
    max_time: float  # [s] a trip not done by then counts as failed
    weights: Weights
    #: (low, high) of kx, ky, ktheta; the search runs over their log10.
    bounds: tuple[tuple[float, float], ...] = (GAIN_RANGE, GAIN_RANGE, GAIN_RANGE)
    #: The gains to beat (the paper's), if the target has any.
    reference: Gains | None = None

    @property
    def trips(self) -> int:
        return int(self.starts.shape[0])


@dataclass(frozen=True)
class Scores:
    """Per-candidate means over the target's trips (arrays of shape (S,))."""

    effort: FloatArray
    distance: FloatArray  # [m]
    time: FloatArray  # [s]; failed trips count max_time
    done: FloatArray  # fraction of trips within tolerance
    cost: FloatArray
    turns: FloatArray  # [revolutions] the whole rotation of a trip (module docstring)

    def row(self, i: int) -> dict[str, float]:
        return {
            "effort": float(self.effort[i]),
            "distance": float(self.distance[i]),
            "time": float(self.time[i]),
            "done": float(self.done[i]),
            "cost": float(self.cost[i]),
            "turns": float(self.turns[i]),
        }


@dataclass
class TuneResult:
    """Best gains found, their scores, the reference's, and every candidate evaluated."""

    target: TuneTarget
    best: Gains
    best_scores: dict[str, float]
    reference_scores: dict[str, float] | None
    evaluated_gains: FloatArray  # (K, 3)
    evaluated: Scores = field(repr=False)
    generations: int = 0

    @property
    def beats_reference(self) -> bool:
        """True when the best gains need less effort *and* distance than the reference."""
        ref = self.reference_scores
        return (
            ref is not None
            and self.best_scores["done"] == 1.0
            and self.best_scores["effort"] < ref["effort"]
            and self.best_scores["distance"] < ref["distance"]
        )


def case_target(
    case: CaseName,
    law: Law,
    weights: Weights = CASE_WEIGHTS,
    profile: RobotProfile | None = None,
    max_time: float | None = None,
) -> TuneTarget:
    """One of the paper's scenarios at dt = 0.01 s with its tolerance; the paper's gains
    for ``law`` are the reference. ``profile`` defaults to the Table 10 robot with the
    fleet's 20 rad/s wheel limit. ``max_time`` [s] defaults to three times the reference's
    arrival time under that robot (within [20, 300] s): slower candidates count as failed.
    """
    scenario = SCENARIOS[case]
    target = TuneTarget(
        name=case,
        law=law,
        starts=np.array([scenario.start], dtype=np.float64),
        goals=np.array([scenario.goal], dtype=np.float64),
        tolerance=scenario.tolerance,
        profile=profile if profile is not None else RobotProfile(),
        dt=PAPER_DT,
        max_time=MAX_CASE_TIME if max_time is None else max_time,
        weights=weights,
        reference=scenario.gains[law],
    )
    if max_time is None:
        reference = score(target, [scenario.gains[law].as_tuple()])
        arrival = float(reference.time[0]) if reference.done[0] else MAX_CASE_TIME
        target = replace(target, max_time=min(max(3.0 * arrival, 20.0), MAX_CASE_TIME))
    return target


def yard_trips(
    count: int, seed: int, half: float = 5.0, spacing: float = 1.5
) -> tuple[FloatArray, FloatArray]:
    """``count`` trips in a ``2 half`` x ``2 half`` m yard: start and goal positions uniform,
    at least ``spacing`` [m] apart, headings uniform in [-pi, pi) (as the fleet benchmark's
    random yards). Returns (starts, goals), each (count, 3)."""
    if count < 1:
        raise ValueError("count must be at least 1")
    rng = np.random.default_rng(seed)
    starts = np.empty((count, 3))
    goals = np.empty((count, 3))
    k = 0
    while k < count:
        a, b = rng.uniform(-half, half, size=(2, 2))
        if math.hypot(*(a - b)) < spacing:
            continue
        heads = rng.uniform(-math.pi, math.pi, size=2)
        starts[k] = (a[0], a[1], heads[0])
        goals[k] = (b[0], b[1], heads[1])
        k += 1
    return starts, goals


def yard_target(
    law: Law,
    trips: int = 200,
    seed: int = 2026,
    weights: Weights = YARD_WEIGHTS,
    max_kx: float | None = None,
    max_time: float = 90.0,
) -> TuneTarget:
    """Typical yard trips (:func:`yard_trips`) for the fleet's robot, time first; the
    reference is the paper's Table 1 gains for ``law`` (chosen for one 10 m trip).
    ``max_kx`` [1/s] defaults to :data:`YARD_MAX_KX` of the law."""
    if max_kx is None:
        max_kx = YARD_MAX_KX[law]
    if not GAIN_RANGE[0] < max_kx:
        raise ValueError(f"max_kx must exceed {GAIN_RANGE[0]}")
    starts, goals = yard_trips(trips, seed)
    return TuneTarget(
        name="yard",
        law=law,
        starts=starts,
        goals=goals,
        tolerance=YARD_TOLERANCE,
        profile=RobotProfile(),
        dt=YARD_DT,
        max_time=max_time,
        weights=weights,
        bounds=((GAIN_RANGE[0], max_kx), GAIN_RANGE, GAIN_RANGE),
        reference=SCENARIOS["first"].gains[law],
    )


def score(target: TuneTarget, gains: npt.ArrayLike) -> Scores:
    """Score S candidate gain triples (S, 3) on every trip, in one simulator batch."""
    g = np.atleast_2d(np.asarray(gains, dtype=np.float64))
    if g.ndim != 2 or g.shape[1] != 3:
        raise ValueError(f"gains must have shape (S, 3), got {g.shape}")
    s, m = g.shape[0], target.trips
    problem = BatchProblem.build(
        np.tile(target.starts, (s, 1)),
        np.tile(target.goals, (s, 1)),
        np.repeat(g, m, axis=0),
        target.law,
        tolerance=target.tolerance,
        profile=target.profile,
    )
    result = simulate(problem, dt=target.dt, max_time=target.max_time)
    done = result.done.reshape(s, m)
    time = np.where(done, result.time.reshape(s, m), target.max_time)
    effort = result.control_effort.reshape(s, m).mean(axis=1)
    distance = result.distance.reshape(s, m).mean(axis=1)
    mean_time = time.mean(axis=1)
    done_rate = done.mean(axis=1)
    start_heading = np.tile(target.starts[:, 2], s)
    turned = np.abs(result.final_pose[:, 2] - start_heading) / (2.0 * math.pi)
    turns = turned.reshape(s, m).mean(axis=1)
    w = target.weights
    cost = (
        w.effort * effort
        + w.distance * distance
        + w.time * mean_time
        + w.turns * turns
        + FAIL_PENALTY * (1.0 - done_rate)
    )
    return Scores(effort, distance, mean_time, done_rate, cost, turns)


def _concat(parts: list[Scores]) -> Scores:
    return Scores(
        *(np.concatenate([getattr(p, k) for p in parts]) for k in Scores.__dataclass_fields__)
    )


def tune(
    target: TuneTarget,
    seed: int = 0,
    popsize: int = 15,
    generations: int = 60,
    progress: Callable[[int, float], None] | None = None,
) -> TuneResult:
    """Differential evolution over log10 gains; each generation is one simulator batch.

    ``popsize`` is scipy's multiplier (population = popsize x 3); ``generations`` bounds
    the iterations; ``progress(generation, best cost)`` is called after each one.
    """
    if popsize < 2 or generations < 1:
        raise ValueError("popsize must be >= 2 and generations >= 1")
    log_bounds = [(math.log10(lo), math.log10(hi)) for lo, hi in target.bounds]
    seen_gains: list[FloatArray] = []
    seen_scores: list[Scores] = []

    def cost(x: FloatArray) -> FloatArray:
        gains = (10.0 ** np.asarray(x, dtype=np.float64)).T.reshape(-1, 3)
        scores = score(target, gains)
        seen_gains.append(gains)
        seen_scores.append(scores)
        return scores.cost

    count = [0]

    def callback(*_args: object, **_kwargs: object) -> None:
        count[0] += 1
        if progress is not None:
            best = min(float(s.cost.min()) for s in seen_scores)
            progress(count[0], best)

    # scipy on first use: ``parkfleet`` builds every command's parser, also on a robot's
    # install (the ``robot`` extra), which has no scipy.
    from scipy.optimize import differential_evolution

    found = differential_evolution(
        cost,
        log_bounds,
        seed=seed,
        popsize=popsize,
        maxiter=generations,
        vectorized=True,
        updating="deferred",
        polish=False,
        tol=1e-6,
        callback=callback,
    )
    kx, ky, ktheta = (10.0 ** np.asarray(found.x, dtype=np.float64)).tolist()
    best = Gains(kx=kx, ky=ky, ktheta=ktheta)
    rows = [best.as_tuple()]
    if target.reference is not None:
        rows.append(target.reference.as_tuple())
    finals = score(target, rows)
    return TuneResult(
        target=target,
        best=best,
        best_scores=finals.row(0),
        reference_scores=finals.row(1) if target.reference is not None else None,
        evaluated_gains=np.concatenate(seen_gains),
        evaluated=_concat(seen_scores),
        generations=count[0],
    )


def pareto_front(effort: npt.ArrayLike, distance: npt.ArrayLike) -> npt.NDArray[np.intp]:
    """Indices of the points no other point beats on both effort and distance, sorted by
    effort (a point equal to another on both counts once)."""
    e = np.asarray(effort, dtype=np.float64)
    d = np.asarray(distance, dtype=np.float64)
    order = np.lexsort((d, e))
    front: list[int] = []
    best_d = math.inf
    for i in order:
        if d[i] < best_d:
            front.append(int(i))
            best_d = float(d[i])
    return np.asarray(front, dtype=np.intp)
