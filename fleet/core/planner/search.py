"""The search of one cluster: which law, start delay or hold for each of its robots (pure).

A :class:`ClusterSearch` proposes candidates in *rounds*; the planner rolls out the
candidates of every cluster's round together (one simulator call per round and size
bucket, :mod:`fleet.core.planner.rollout`) and sends back their scores
(:mod:`fleet.core.planner.cost`). Rounds:

1. **Baseline** (one round): what the robots do now (robots under way keep their law and
   delay, held robots stay held, new robots take their fastest solo law at once), each
   robot under way on its last leg within ``flip_within_m`` of its goal whose other law
   alone arrives more than ``flip_gain_s`` sooner with that law (and all of them
   together), the
   seeds the planner passes (the prioritised plan on the solo predictions,
   :mod:`fleet.core.planner.reserve`, or the plans of clusters now merged), held robots
   released,
   the uniform choices (every free robot ccw, every free robot cw), -- with at most
   ``exhaustive_limit`` robots free to choose -- every combination of laws, and -- with
   six new robots or more routed round one lone post or wall -- an order in two waves:
   every other one of them round it waits each of ``delays_s`` (robots crowding a
   roundabout fill the circle round its zone and crawl all at once; docs/benchmarks.md,
   eighteenth stop).
2. **Local search** (up to ``rounds`` rounds, ``budget`` rollouts): from the best so far,
   single-robot moves, all rolled out in one round. When the best is unsafe, for the robots
   of its closest pairs: flip the law, wait longer (``delays_s`` added to the start delay),
   hold. When it is safe: release held robots (each law, each delay), flip the law of the
   latest robot, make the robots it meets wait or flip, shorten delays. A round that finds
   nothing better ends the search, as does a safe plan within ``good_enough`` of the solo
   lower bound.
3. **Never unsafe** (outside the budget): while the best is still unsafe, the robots of its
   violating pairs hold -- new and held robots first, robots under way when only they are
   left -- and the result is rolled out again. Holding every robot is safe (nobody moves),
   so this ends within as many rounds as the cluster has robots.

Candidates are memoised; a held robot's law and delay are normalised, so equivalent
candidates are rolled out once. Once a safe plan with every robot arriving is known,
rollouts stop shortly after its makespan (a slower candidate cannot win).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from fleet.core.planner.clusters import Cluster
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.cost import Score
from fleet.core.planner.scene import HELD, NEW, UNDER_WAY, Candidate, Fleet, route_clearance
from fleet.core.types import IntArray

#: [s] rollouts run this long past the best known makespan (see the module docstring).
_CUT_MARGIN = 1.0
#: New robots routed round one lone obstacle from which the baseline also tries two waves.
_WAVE_MIN = 6


class ClusterSearch:
    """The rounds of one cluster's search (see the module docstring).

    Call :meth:`start` for the first round's candidates, then :meth:`send` with their
    scores (same order) until it returns None; :attr:`best` is the choice.
    """

    def __init__(
        self,
        fleet: Fleet,
        cluster: Cluster,
        config: PlannerConfig,
        seeds: Sequence[Candidate] = (),
        budget: int | None = None,
        improve: bool = True,
    ) -> None:
        self.fleet, self.cluster, self.config = fleet, cluster, config
        self.budget = config.budget if budget is None else budget
        self.improve = improve
        m = fleet.movers
        idx = np.asarray(cluster.movers, dtype=np.int64)
        self._idx = idx
        self._kind = m.kind[idx]
        self._allowed = m.allowed[idx]
        self._blocks = fleet.blocks[np.ix_(idx, idx)]
        solo = fleet.solo_time[idx]
        self.solo = np.where(np.isfinite(solo), solo, config.max_horizon_s)
        keep_delay = m.keep_delay[idx]
        fastest = np.min(np.where(self._allowed, solo, np.inf), axis=1)
        kept = solo[np.arange(idx.size), m.keep_law[idx]] + keep_delay
        lower = np.where(self._kind == UNDER_WAY, np.minimum(fastest, kept), fastest)
        self.lower_bound = float(lower.max()) if idx.size else 0.0
        longest = self.lower_bound if np.isfinite(self.lower_bound) else config.max_horizon_s
        self.horizon = float(
            np.clip(
                config.horizon_factor * longest + 2 * max(config.delays_s, default=0.0),
                config.min_horizon_s,
                config.max_horizon_s,
            )
        )
        self.max_delay = 2 * max(config.delays_s, default=0.0)
        #: new or held robots: worth improving; otherwise a safe "keep" is the answer
        self.fresh = bool(np.isin(self._kind, (NEW, HELD)).any())
        self.memo: dict[bytes, Score] = {}
        self.best: Score | None = None
        self.rollouts = 0
        self._seeds = [self.normalise(s) for s in seeds]
        self._phase = "baseline"
        self._rounds = 0
        self._spent = 0
        self._line_key: tuple[float, ...] | None = None

    # -- candidates ------------------------------------------------------------------------

    @property
    def size(self) -> int:
        return int(self._idx.size)

    def keep(self) -> Candidate:
        return self.fleet.keep(self.cluster.movers)

    def normalise(self, c: Candidate) -> Candidate:
        """Held robots -- and those waiting for a zone, which always hold -- the law they
        keep and no delay (equivalent candidates, one key)."""
        keep = self.keep()
        hold = c.hold | self.fleet.forced(self._idx)
        law = np.where(hold, keep.law, c.law)
        delay = np.where(hold, 0.0, np.clip(c.delay, 0.0, None))
        return Candidate(law.astype(np.int64), delay, hold)

    def _flippable(self, i: int) -> bool:
        return bool(self._allowed[i].all())

    def _baseline(self) -> list[Candidate]:
        keep = self.keep()
        out = [keep, *self._faster_flips(keep), *self._seeds]
        released = Candidate(keep.law.copy(), keep.delay.copy(), np.zeros(self.size, dtype=bool))
        if keep.hold.any():
            out.append(released)
        free = [i for i in range(self.size) if self._flippable(i) and self._kind[i] != UNDER_WAY]
        for law in (0, 1):
            c = Candidate(released.law.copy(), released.delay.copy(), released.hold.copy())
            c.law[free] = law
            out.append(c)
        if 0 < len(free) <= self.config.exhaustive_limit:
            for combo in itertools.product((0, 1), repeat=len(free)):
                c = Candidate(released.law.copy(), released.delay.copy(), released.hold.copy())
                c.law[free] = combo
                out.append(c)
        later = self._every_other_round()
        for d in self.config.delays_s if len(later) else ():
            c = Candidate(released.law.copy(), released.delay.copy(), released.hold.copy())
            c.delay[later] += d
            out.append(c)
        return out

    def _faster_flips(self, keep: Candidate) -> list[Candidate]:
        """``keep`` with each robot under way flipped that drives straight to its goal from
        within ``flip_within_m`` of it and whose other law, alone from where it is (the solo
        predictions), arrives more than ``flip_gain_s`` sooner, and with all of them
        flipped (the cost's change penalty still has to be paid)."""
        m, rows = self.fleet.movers, np.arange(self.size)
        gain = self.solo[rows, keep.law] - self.solo[rows, 1 - keep.law]
        near = np.hypot(*(m.start[self._idx, :2] - m.goal[self._idx, :2]).T)
        flips = [
            i
            for i in rows.tolist()
            if self._kind[i] == UNDER_WAY
            and not keep.hold[i]
            and self._flippable(i)
            and gain[i] > self.config.flip_gain_s
            and near[i] <= self.config.flip_within_m
            and not (m.route and len(m.route[int(self._idx[i])]))
        ]
        out = [keep.with_(i, law=1 - int(keep.law[i])) for i in flips]
        if len(flips) > 1:
            every = Candidate(keep.law.copy(), keep.delay.copy(), keep.hold.copy())
            every.law[flips] = 1 - every.law[flips]
            out.append(every)
        return out

    def _every_other_round(self) -> IntArray:
        """The second wave of an order "these go, those follow" at a roundabout: when at
        least ``_WAVE_MIN`` new robots are routed round one lone obstacle
        (:func:`~fleet.core.planner.roadmap.roundabout_islands`: a via-point within its
        zone and two route clearances), every other one of them taken round its centre.
        All at once they fill the circle round its zone and crawl; none of the second wave
        stands on a goal of the first when goals are each other's starts (a ring). Empty:
        none."""
        fleet, none = self.fleet, np.zeros(0, dtype=np.int64)
        new = np.flatnonzero(self._kind == NEW)
        if len(new) < _WAVE_MIN or not fleet.world.obstacles or not fleet.movers.route:
            return none
        from fleet.core.planner.roadmap import roundabout_islands  # shapely: the planner's

        clearance = route_clearance(fleet.movers.limits, fleet.world, self.config)
        for island in roundabout_islands(fleet.world.obstacles, clearance):
            reach = island.radius + 2.0 * clearance
            cx, cy = (np.array([island.x, island.y]) + island.far_end) / 2.0
            users, bearings = [], []
            for i in new.tolist():
                via = fleet.movers.route[int(self._idx[i])]
                if any(island.distance(float(x), float(y)) <= reach for x, y in via):
                    start = fleet.movers.start[int(self._idx[i])]
                    users.append(i)
                    bearings.append(np.arctan2(start[1] - cy, start[0] - cx))
            if len(users) >= _WAVE_MIN:
                order = np.asarray(users)[np.argsort(bearings, kind="stable")]
                return np.asarray(order[1::2], dtype=np.int64)
        return none

    def _repairs(self, best: Score) -> list[Candidate]:
        """Moves for the robots of an unsafe candidate's closest pairs."""
        c = best.candidate
        k = self.size
        out: list[Candidate] = []
        targets: list[int] = []
        for v in best.violations:  # earliest first
            for r in (v.a, v.b):
                if r < k and r not in targets and not c.hold[r]:
                    targets.append(r)
        # against a robot that stands, waiting does not help: only a law change or a hold
        pinned = {v.a for v in best.violations if v.standing}
        for i in targets[: self.config.repair_targets]:
            if self._flippable(i):
                out.append(c.with_(i, law=1 - int(c.law[i])))
            for d in () if i in pinned else self.config.delays_s:
                if c.delay[i] + d <= self.max_delay + 1e-9:
                    out.append(c.with_(i, delay=float(c.delay[i]) + d))
            out.append(c.with_(i, hold=True))
        return out

    def _improvements(self, best: Score) -> list[Candidate]:
        """Moves that may shorten a safe candidate: release held robots, speed up the
        latest robot and those it meets, give robots their fastest law, shorten delays."""
        c = best.candidate
        k = self.size
        delays = self.config.delays_s
        out: list[Candidate] = []
        for i in np.flatnonzero(c.hold):
            for law in (law for law in (0, 1) if self._allowed[i, law]):
                for d in (0.0, *delays):
                    out.append(c.with_(int(i), law=law, delay=d, hold=False))
        arrival = np.where(np.isnan(best.arrival), -np.inf, best.arrival)
        if np.isfinite(arrival).any():
            late = int(np.argmax(arrival))
            if self._flippable(late):
                out.append(c.with_(late, law=1 - int(c.law[late])))
            if c.delay[late] > 0:
                out.append(c.with_(late, delay=0.0))
            reach = self.fleet.world.avoidance.peer_radius + self.fleet.separation
            for j in (int(v) for v in np.flatnonzero(best.pair_min[late, :k] < reach)):
                if c.hold[j]:
                    continue
                if self._flippable(j):
                    out.append(c.with_(j, law=1 - int(c.law[j])))
                for d in delays[:2]:
                    out.append(c.with_(j, delay=float(c.delay[j]) + d))
        # robots on their slower law, the biggest solo gain first
        solo = self.solo
        moving = ~c.hold & self._allowed.all(axis=1)
        gain = np.where(moving, solo[np.arange(k), c.law] - solo[np.arange(k), 1 - c.law], 0.0)
        for i in np.argsort(-gain, kind="stable"):
            if gain[i] > 0:
                out.append(c.with_(int(i), law=1 - int(c.law[i])))
        for i in np.flatnonzero((c.delay > 0) & ~c.hold):
            out.append(c.with_(int(i), delay=0.0))
            out.append(c.with_(int(i), delay=float(c.delay[i]) / 2))
        return out

    def _promising(self, best: Score) -> Score | None:
        """The unsafe line worth repairing beside a safe ``best``: among unsafe candidates
        whose solo estimate beats ``best``'s total, the one whose first conflict is latest."""
        return min(
            (
                s
                for s in self.memo.values()
                if not s.safe and s.held == 0 and s.estimate < best.total
            ),
            key=lambda s: s.key,
            default=None,
        )

    def _neighbours(self, best: Score) -> list[Candidate]:
        if not best.safe:
            return self._repairs(best)
        improve = self._improvements(best)
        line = self._promising(best)
        if line is None:
            return improve
        repair = self._repairs(line)
        half = max(1, len(improve) // 2)
        return improve[:half] + repair + improve[half:]

    def _safety_net(self, best: Score) -> list[Candidate]:
        """``best`` with more robots held, from one per violating pair (new and held robots
        first, and of two the one that would not trap the other by parking on its way) to
        every robot (safe: nobody moves); see the module docstring."""
        c = best.candidate
        k = self.size
        kind = self._kind
        one, both = c.hold.copy(), c.hold.copy()
        blocks = self._blocks
        for v in best.violations:
            side = [r for r in (v.a, v.b) if r < k and not c.hold[r]]
            both[side] = True
            if not side or one[side].any():
                continue
            fresh = [r for r in side if kind[r] in (NEW, HELD)]
            if fresh:  # hold the one that would not trap the other by parking on its way
                one[max(fresh, key=lambda r: (not blocks[r].any(), kind[r] == NEW, r))] = True
            else:
                one[side] = True
        new = c.hold | (kind != UNDER_WAY)
        every = np.ones(k, dtype=bool)
        return [
            self.normalise(Candidate(c.law.copy(), c.delay.copy(), hold))
            for hold in (one, both, new | both, every)
        ]

    # -- rounds ----------------------------------------------------------------------------

    @property
    def run_horizon(self) -> float:
        """How long the next round's rollouts need to run [s]."""
        b = self.best
        if b is not None and b.safe and b.held == 0 and b.unfinished == 0:
            cut = b.makespan + b.penalty_s * b.changes + _CUT_MARGIN
            return float(min(self.horizon, max(cut, self.fleet.dt)))
        return self.horizon

    def _fresh(self, candidates: Sequence[Candidate], limit: int | None = None) -> list[Candidate]:
        out: list[Candidate] = []
        seen: set[bytes] = set()
        for c in candidates:
            c = self.normalise(c)
            key = c.key()
            if key in self.memo or key in seen:
                continue
            seen.add(key)
            out.append(c)
            if limit is not None and len(out) >= limit:
                break
        return out

    def start(self) -> list[Candidate]:
        return self._fresh(self._baseline())

    def _good_enough(self, b: Score) -> bool:
        if not b.safe or b.held or b.unfinished:
            return False
        if not self.fresh:  # robots under way only: keep what is safe (stable decisions)
            return True
        return b.makespan <= self.config.good_enough * self.lower_bound + 0.5

    def _remember(self, scores: Sequence[Score]) -> None:
        """Memoise ``scores``, keeping the rollout of the best only (memory)."""
        for s in scores:
            self.memo[s.candidate.key()] = replace(s, outcome=None) if s is not self.best else s

    def send(self, scores: Sequence[Score]) -> list[Candidate] | None:
        """Scores of the last round's candidates; the next round's, or None when done."""
        self.rollouts += len(scores)
        before = self.best
        if self._phase == "net":
            # the net candidate with the best key among the safe ones (all held is safe)
            safe = [s for s in scores if s.safe]
            if safe:
                self.best = min(safe, key=lambda s: s.key)
            self._remember(scores)
            self._drop(before)
            return None
        for s in scores:
            if self.best is None or s.key < self.best.key:
                self.best = s
        self._remember(scores)
        self._drop(before)
        best = self.best
        if best is None:
            return None
        if self._phase != "baseline":
            self._spent += len(scores)
        line = self._promising(best) if best.safe else None
        line_key = None if line is None else line.key
        stuck = self._phase != "baseline" and best is before and line_key == self._line_key
        self._line_key = line_key
        phase = "repair" if not best.safe else "improve"
        if phase != self._phase:
            self._phase, self._rounds, stuck = phase, 0, False
        limit = self.config.rounds if phase == "repair" else self.config.improve_rounds
        if phase == "improve" and not self.improve:
            limit = 0
        left = self.budget - self._spent
        if phase == "improve":
            left = min(left, self.config.improve_candidates)
        if not stuck and self._rounds < limit and left > 0 and not self._good_enough(best):
            self._rounds += 1
            nxt = self._fresh(self._neighbours(best), limit=left)
            if nxt:
                return nxt
        if best.safe:
            return None
        self._phase = "net"
        variants = self._safety_net(best)
        nxt = self._fresh(variants)
        if not nxt:  # every variant was rolled out already: take the best safe one
            known = [self.memo[v.key()] for v in variants]
            self.best = min((s for s in known if s.safe), key=lambda s: s.key)
            return None
        return nxt

    def _drop(self, old: Score | None) -> None:
        """Forget the rollout of a best that was replaced."""
        if old is not None and old is not self.best:
            key = old.candidate.key()
            self.memo[key] = replace(old, outcome=None)


__all__ = ["ClusterSearch"]
