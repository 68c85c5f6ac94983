"""The cost of a candidate plan for one cluster, from its rollout (pure).

Lexicographic, smaller is better (:attr:`Score.key`):

1. **safety** -- every pair involving a moving robot keeps ``separation`` [m] over the
   whole run (a pair that starts closer must not get closer than it started). An unsafe
   candidate ranks after every safe one; its rollout stopped at the first violation, so
   unsafe ones rank by holds, then the *later* their first violation the better (conflicts
   are resolved in time order) -- a violation with a robot that stands (a standing row)
   counts as at once: waiting cannot fix it --, then by how many pairs violate, then by
   the solo estimate of their arrivals (each robot's delay plus its solo time with its
   law);
2. **trapped** -- held robots that a robot this plan moves will trap by parking on their
   way (``Fleet.blocks``): such a hold would never be released;
3. **not arriving** -- robots that hold (a robot waiting for a single-robot zone holds in
   every candidate and is not counted) plus moving robots that do not arrive within the
   horizon (*unfinished*): a hold pays where it lets more robots arrive than it stops --
   the filter would jam them otherwise -- and a robot that arrives neither way moves;
   then **held**: a hold is the last resort;
4. **makespan** -- the latest predicted arrival of a moving robot [s], plus
   ``change_penalty_s`` per change to a robot under way (a flip, a new delay, a hold): a
   change must pay for itself, so a stable plan stays stable;
5. the **sum of arrival times plus driving times** [s] (distance driven / top speed, so a
   plan whose robots wander round each other costs more; same penalty).

Arrival times count from the moment the plan reaches the robots; a robot that does not
arrive counts ``horizon + remaining distance / top speed``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.planner.rollout import Outcome, Rows
from fleet.core.planner.scene import NEW, Candidate, Fleet
from fleet.core.types import BoolArray, FloatArray, IntArray

#: Below this shortfall [m] a pair counts as keeping its distance (rounding).
_EPS = 1e-9


@dataclass(frozen=True)
class Violation:
    """A pair of rows of a cluster's rollout that came closer than allowed [m], first at
    about ``time`` [s]."""

    a: int
    b: int
    distance: float
    allowed: float
    time: float
    standing: bool = False  # b is a standing row: only a law change or a hold helps


@dataclass(frozen=True)
class Score:
    """One candidate's rollout scored (see the module docstring)."""

    candidate: Candidate
    shortfall: float  # [m] >= 0
    held: int
    trapped: int
    unfinished: int
    makespan: float  # [s] without penalties
    total: float  # [s] without penalties
    changes: int
    min_separation: float  # [m] over pairs involving a moving robot
    arrival: FloatArray  # (k,) [s] per mover; NaN when held
    separation: FloatArray  # (k,) [m] each mover's closest approach to any other row
    pair_min: FloatArray  # (n, n) [m] closest approach of each pair of rows
    violations: tuple[Violation, ...]
    penalty_s: float
    stopped_at: float  # [s] where the rollout ended (the first violation, if unsafe)
    estimate: float  # [s] arrivals so far plus, for the others, delay + solo time
    outcome: Outcome | None = None  # the rollout (kept for the chosen candidate only)

    @property
    def safe(self) -> bool:
        return self.shortfall <= _EPS

    @property
    def key(self) -> tuple[float, float, float, float, float, float]:
        """Smaller is better (see the module docstring)."""
        p = self.penalty_s * self.changes
        if not self.safe:
            first = min((0.0 if v.standing else v.time for v in self.violations), default=0.0)
            return (1.0, self.held, -first, len(self.violations), self.estimate + p, 0.0)
        return (
            0.0,
            self.trapped,
            self.held + self.unfinished,
            self.held,
            self.makespan + p,
            self.total + p,
        )


def changes(fleet: Fleet, movers: Sequence[int], c: Candidate) -> int:
    """Changes to robots already under way or held (flip, new delay, hold; not a release)."""
    m = fleet.movers
    idx = np.asarray(movers, dtype=np.int64)
    old = m.kind[idx] != NEW
    hold_now = m.keep_hold[idx]
    moving = ~c.hold & ~hold_now
    flipped = moving & (c.law != m.keep_law[idx])
    delayed = moving & (np.abs(c.delay - m.keep_delay[idx]) > 1e-6)
    newly_held = c.hold & ~hold_now
    return int(np.count_nonzero(old & (flipped | delayed | newly_held)))


@dataclass(frozen=True)
class Limits:
    """Which pairs of a rollout's rows count and how close they may come [m]."""

    allowed: FloatArray  # (n, n)
    involved: BoolArray  # (n, n): at least one of the pair moves

    @staticmethod
    def of(separation: float, rows: Rows, moving: BoolArray) -> Limits:
        """Pairs involving a ``moving`` row (k,) of ``rows`` keep ``separation``, or, if
        they start closer, do not get closer than they start."""
        n = rows.size
        moving_row = np.zeros(n, dtype=bool)
        moving_row[: moving.size] = moving
        xy = rows.start[:, :2]
        d0 = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
        involved = moving_row[:, None] | moving_row[None, :]
        np.fill_diagonal(involved, False)
        return Limits(np.minimum(separation, d0 - _EPS), involved)

    def gap(self, min_pair: FloatArray) -> FloatArray:
        """(n, n) how far each counted pair fell short [m] (-inf for pairs not counted)."""
        return np.where(self.involved, self.allowed - min_pair, -np.inf)

    def broken(self, min_pair: FloatArray) -> bool:
        return bool(self.involved.any()) and float(self.gap(min_pair).max()) > _EPS


def trapped(fleet: Fleet, movers: Sequence[int], c: Candidate) -> int:
    """Held movers whose every way is blocked by the goal of a mover ``c`` moves."""
    idx = np.asarray(movers, dtype=np.int64)
    blocks = fleet.blocks[np.ix_(idx, idx)]
    return int(np.count_nonzero(c.hold & (blocks & ~c.hold[None, :]).any(axis=1)))


def _first_below(
    outcome: Outcome, a: IntArray, b: IntArray, allowed: FloatArray, default: float
) -> FloatArray:
    """When each pair (a[p], b[p]) first came closer than ``allowed[p]`` in the recorded
    samples [s] (``default`` where the samples missed it)."""
    when = np.full(a.size, default)
    if outcome.xy is None or outcome.times is None or a.size == 0:
        return when
    d = np.hypot(*(outcome.xy[:, a] - outcome.xy[:, b]).transpose(2, 0, 1))
    below = d < allowed[None, :]
    hit = below.any(axis=0)
    when[hit] = outcome.times[np.argmax(below, axis=0)[hit]]
    return when


def score(
    fleet: Fleet,
    movers: Sequence[int],
    c: Candidate,
    rows: Rows,
    outcome: Outcome,
    horizon: float,
    penalty_s: float,
    solo: FloatArray,
) -> Score:
    """Score ``c`` (options of ``movers``) from its rollout ``outcome`` of ``rows``;
    ``solo`` (k, 2) are the movers' solo times per law [s]."""
    k = len(movers)
    n = rows.size
    limits = Limits.of(fleet.separation, rows, ~c.hold)
    allowed, involved = limits.allowed, limits.involved
    assert outcome.min_pair is not None
    gap = limits.gap(outcome.min_pair)
    shortfall = float(gap.max()) if n > 1 else -np.inf
    near = np.where(involved, outcome.min_pair, np.inf)
    min_sep = float(near.min()) if n > 1 else float("inf")
    per_row = near.min(axis=1) if n > 1 else np.full(n, np.inf)
    stopped_at = outcome.steps * fleet.dt
    violations: list[Violation] = []
    if shortfall > _EPS:
        a_idx, b_idx = np.nonzero(np.triu(gap > _EPS))
        when = _first_below(outcome, a_idx, b_idx, allowed[a_idx, b_idx], stopped_at)
        order = np.lexsort((-gap[a_idx, b_idx], when))
        for j in order[:16]:
            a, b = int(a_idx[j]), int(b_idx[j])
            violations.append(
                Violation(a, b, float(outcome.min_pair[a, b]), float(allowed[a, b]), float(when[j]))
            )
    moving = ~c.hold
    remaining = np.hypot(
        outcome.final[:k, 0] - rows.goal[:k, 0], outcome.final[:k, 1] - rows.goal[:k, 1]
    )
    done = outcome.done[:k]
    arrival = np.where(done, outcome.time[:k], horizon + remaining / fleet.top_speed)
    arrival = np.where(moving, arrival, np.nan)
    unfinished = int(np.count_nonzero(moving & ~done))
    guess = np.maximum(c.delay + solo[np.arange(k), c.law], stopped_at)
    estimate = float(np.sum(np.where(moving, np.where(done, outcome.time[:k], guess), 0.0)))
    return Score(
        candidate=c,
        shortfall=max(shortfall, 0.0),
        held=int(np.count_nonzero(c.hold & ~fleet.forced(np.asarray(movers, dtype=np.int64)))),
        trapped=trapped(fleet, movers, c),
        unfinished=unfinished,
        makespan=float(np.nanmax(arrival)) if moving.any() else 0.0,
        total=float(np.nansum(arrival))
        + float(outcome.distance[:k][moving].sum()) / fleet.top_speed,
        changes=changes(fleet, movers, c),
        min_separation=min_sep,
        arrival=arrival,
        separation=per_row[:k].copy(),
        pair_min=outcome.min_pair,
        violations=tuple(violations),
        penalty_s=penalty_s,
        stopped_at=stopped_at,
        estimate=estimate,
        outcome=outcome,
    )


__all__ = ["Limits", "Score", "Violation", "changes", "score", "trapped"]
