"""``plan``: who takes which task, with which law, when -- and who waits (pure).

1. **Assignment** (:mod:`~fleet.core.planner.assign`): queued tasks get available robots.
2. **Scene** (:mod:`~fleet.core.planner.scene`): the robots to decide (new, under way,
   held), the standing robots, the lead-in until the plan reaches the robots, and each
   mover's solo predictions.
3. **Seed and clusters**: a prioritised plan on the solo predictions staggers the robots
   (:mod:`~fleet.core.planner.reserve`, no simulation); robots whose staggered paths come
   within the peer radius (+ a margin) of each other at about the same time are searched
   together, the others apart (:mod:`~fleet.core.planner.clusters`). Standing robots
   (lost ones too) join only the clusters that pass near them.
4. **Search** (:mod:`~fleet.core.planner.search`): per cluster a law, a start delay or a
   hold for every robot, by closed-loop rollouts at the agents' step; every cluster's round
   goes to the simulator together (:mod:`~fleet.core.planner.rollout`).
5. **Check**: the chosen plans are rolled out once more, recorded. Clusters whose plans
   now come within the peer radius of each other (or of a standing robot they did not
   know) are merged and searched again, seeded with their plans -- with the full budget
   ``merge_rounds`` times, then with the baseline and the safety net only -- until no
   plan interacts with another cluster's. The recordings give the corridors.

Never unsafe: a cluster's chosen plan keeps ``separation_m`` for every pair involving a
moving robot (the search's safety net holds robots until it does); robots held carry the
reason. Decisions: ``assign`` for new tasks, ``revise`` for a task under way whose law,
delay or hold changes, ``keep`` (with a fresh corridor) otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.planner.assign import pair_queued
from fleet.core.planner.clusters import (
    Cluster,
    clusters,
    components,
    interacting_pairs,
    near_standing,
)
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.corridor import sample_corridor
from fleet.core.planner.cost import Limits, Score, score
from fleet.core.planner.model import Action, Plan, PlanningSnapshot, TaskDecision
from fleet.core.planner.reserve import reservation
from fleet.core.planner.rollout import Live, Outcome, advance
from fleet.core.planner.scene import NEW, Candidate, Fleet, build_fleet, scene_rows
from fleet.core.planner.search import ClusterSearch
from fleet.core.types import LAWS, FloatArray

#: [m] added to the peer radius when checking that chosen plans of clusters stay apart.
_CHECK_MARGIN = 0.1


@dataclass(frozen=True)
class _Settled:
    """A cluster's chosen plan and its recorded rollout."""

    cluster: Cluster
    best: Score
    outcome: Outcome
    reasons: dict[int, str]


def _drive(fleet: Fleet, searches: Sequence[ClusterSearch], config: PlannerConfig) -> None:
    """Run every search's rounds; each round's candidates of all clusters advance together
    in segments, and a candidate stops once done, unsafe, or past its cluster's horizon.

    Segments double from ``segment_s`` (conflicts are mostly early, and a long run then
    costs few calls); each is a whole number of recording periods."""
    every = _record_every(fleet, config)
    period = every * fleet.dt
    pending = {i: s.start() for i, s in enumerate(searches)}
    while pending:
        jobs = []
        for i, cands in pending.items():
            s = searches[i]
            for c in cands:
                rows = scene_rows(fleet, s.cluster.movers, s.cluster.standing, c)
                jobs.append((i, c, rows, Live(rows), Limits.of(fleet.separation, rows, ~c.hold)))
        limit = {i: searches[i].run_horizon for i in pending}
        segment = period * max(1, round(config.segment_s / period))
        while True:
            live = [j for j in jobs if not j[3].stopped]
            if not live:
                break
            advance(
                [j[3] for j in live],
                fleet.world,
                dt=fleet.dt,
                duration=segment,
                record_every=every,
                max_rows=config.max_rows_per_call,
            )
            segment *= 2
            for i, _, _, lv, lim in live:
                if lv.elapsed >= limit[i] - 1e-9 or lim.broken(lv.min_pair):
                    lv.stopped = True
        scores: dict[int, list[Score]] = {i: [] for i in pending}
        for i, c, rows, lv, _ in jobs:
            s = searches[i]
            scores[i].append(
                score(
                    fleet,
                    s.cluster.movers,
                    c,
                    rows,
                    lv.outcome(),
                    s.horizon,
                    config.change_penalty_s,
                    s.solo,
                )
            )
        nxt = {}
        for i in pending:
            more = searches[i].send(scores[i])
            if more:
                nxt[i] = more
        pending = nxt


def _record_every(fleet: Fleet, config: PlannerConfig) -> int:
    """Steps between recorded positions (the clusters' sample period)."""
    return max(1, round(config.sample_period_s / fleet.dt))


def _hold_reasons(fleet: Fleet, search: ClusterSearch) -> dict[int, str]:
    """Why each held robot of the chosen plan holds: the closest call of its best release."""
    best = search.best
    assert best is not None
    out: dict[int, str] = {}
    ids = [fleet.movers.robot_ids[i] for i in search.cluster.movers]
    ids += [fleet.standing_ids[j] for j in search.cluster.standing]
    for pos in (int(v) for v in np.flatnonzero(best.candidate.hold)):
        released = [s for s in search.memo.values() if not s.candidate.hold[pos]]
        me = ids[pos]
        if not released:
            out[pos] = f"waiting: {me} has no safe option yet (not rolled out)"
            continue
        top = min(released, key=lambda s: s.key)
        mine = [v for v in top.violations if pos in (v.a, v.b)] or list(top.violations)
        if not mine:
            out[pos] = f"waiting: holding {me} keeps the others safe; it will be planned again"
            continue
        v = mine[0]
        other = ids[v.b] if v.a == pos else ids[v.a]
        if pos not in (v.a, v.b):
            other = f"{ids[v.a]} and {ids[v.b]}"
        out[pos] = (
            f"waiting: every option tried for {me} was predicted to bring {other} within "
            f"{v.distance:.2f} m (< {v.allowed:.2f} m)"
        )
    return out


def _settle(fleet: Fleet, searches: Sequence[ClusterSearch]) -> list[_Settled]:
    out = []
    for s in searches:
        assert s.best is not None and s.best.outcome is not None
        out.append(_Settled(s.cluster, s.best, s.best.outcome, _hold_reasons(fleet, s)))
    return out


def _paths(settled: Sequence[_Settled], movers: int) -> tuple[FloatArray, list[int]]:
    """Every mover's recorded positions on one time grid (T, 2), padded with the last."""
    length = max((s.outcome.xy.shape[0] for s in settled if s.outcome.xy is not None), default=1)
    paths = np.zeros((movers, length, 2))
    owner = []
    for s in settled:
        assert s.outcome.xy is not None
        xy = s.outcome.xy
        for pos, i in enumerate(s.cluster.movers):
            n = xy.shape[0]
            paths[i, :n] = xy[:, pos]
            paths[i, n:] = xy[-1, pos]
            owner.append(i)
    return paths, owner


def _merge(fleet: Fleet, settled: Sequence[_Settled], config: PlannerConfig) -> list[list[int]]:
    """Groups of settled clusters (indices) to search again together (each of >= 1 cluster
    whose plan meets another cluster's or a standing robot it did not know)."""
    k = fleet.movers.size
    paths, _ = _paths(settled, k)
    where = np.zeros(k, dtype=np.int64)
    for c, s in enumerate(settled):
        where[list(s.cluster.movers)] = c
    reach = max(fleet.world.avoidance.peer_radius, fleet.separation) + _CHECK_MARGIN
    links = [
        (int(where[i]), int(where[j]))
        for i, j in interacting_pairs(paths, list(range(k)), reach, 1)
        if where[i] != where[j]
    ]
    grown = set()
    for i, j in near_standing(paths, list(range(k)), fleet.standing_xy, reach):
        if j not in settled[int(where[i])].cluster.standing:
            grown.add(int(where[i]))
    groups = components(len(settled), links)
    return [g for g in groups if len(g) > 1 or g[0] in grown]


def _regroup(
    fleet: Fleet, settled: Sequence[_Settled], group: Sequence[int], config: PlannerConfig
) -> tuple[Cluster, Candidate]:
    """One cluster for a group of settled clusters, and the seed their plans make."""
    movers = sorted(i for c in group for i in settled[c].cluster.movers)
    k = fleet.movers.size
    paths, _ = _paths([settled[c] for c in group], k)
    reach = max(fleet.world.avoidance.peer_radius, fleet.separation) + _CHECK_MARGIN
    near = {j for i, j in near_standing(paths[movers], movers, fleet.standing_xy, reach)}
    standing = sorted(near.union(*(settled[c].cluster.standing for c in group)))
    seed = fleet.keep(movers)
    for c in group:
        cand = settled[c].best.candidate
        for pos, i in enumerate(settled[c].cluster.movers):
            j = movers.index(i)
            seed.law[j], seed.delay[j], seed.hold[j] = (
                cand.law[pos],
                cand.delay[pos],
                cand.hold[pos],
            )
    return Cluster(tuple(movers), tuple(standing)), seed


def _initial_clusters(fleet: Fleet, config: PlannerConfig) -> list[tuple[Cluster, list[Candidate]]]:
    """Clusters of the prioritised seed's paths, each with its share of the seed."""
    k = fleet.movers.size
    sep = fleet.separation
    seed, paths = reservation(
        fleet,
        list(range(k)),
        list(range(fleet.standing_xy.shape[0])),
        config.reserve_delays_s,
        sep + config.reserve_margin_m,
        sep + config.reserve_margin_m / 2,
    )
    reach = fleet.world.avoidance.peer_radius + config.interaction_margin_m
    period = fleet.solo_times[1] - fleet.solo_times[0] if fleet.solo_times.size > 1 else 1.0
    window = max(1, round(config.cluster_slack_s / period))
    out = []
    for c in clusters(paths, list(range(k)), k, fleet.standing_xy, reach, window):
        idx = np.asarray(c.movers, dtype=np.int64)
        out.append((c, [Candidate(seed.law[idx], seed.delay[idx], seed.hold[idx])]))
    return out


def _decisions(
    fleet: Fleet, settled: Sequence[_Settled], config: PlannerConfig
) -> list[TaskDecision]:
    m = fleet.movers
    every = max(1, round(config.corridor_period_s / config.sample_period_s))
    out = []
    for s in settled:
        c = s.best.candidate
        o = s.outcome
        assert o.xy is not None and o.times is not None
        for pos, i in enumerate(s.cluster.movers):
            task = m.tasks[i]
            law_i, delay, hold = int(c.law[pos]), float(c.delay[pos]), bool(c.hold[pos])
            kind = int(m.kind[i])
            same = hold == bool(m.keep_hold[i]) and (
                hold or (law_i == int(m.keep_law[i]) and abs(delay - m.keep_delay[i]) <= 1e-6)
            )
            action: Action = "assign" if kind == NEW else "keep" if same else "revise"
            arrival = s.best.arrival[pos]
            out.append(
                TaskDecision(
                    task_id=task.task_id,
                    robot_id=m.robot_ids[i],
                    action=action,
                    law=LAWS[law_i],
                    revision=task.revision,
                    start_delay_s=round(delay, 3),
                    hold=hold,
                    reason=s.reasons.get(pos) if hold else None,
                    predicted_arrival_s=None
                    if hold or not np.isfinite(arrival)
                    else round(float(arrival), 3),
                    corridor=sample_corridor(o.times, o.xy[:, pos], every),
                    predicted_min_separation_m=float(s.best.separation[pos]),
                )
            )
    return out


def plan(snapshot: PlanningSnapshot, config: PlannerConfig | None = None) -> Plan:
    """Decide the queued and under-way tasks of ``snapshot`` (see the module docstring)."""
    config = config or PlannerConfig()
    pairs = pair_queued(snapshot, config)
    fleet = build_fleet(snapshot, pairs, config)
    if fleet.movers.size == 0:
        return Plan(snapshot.version, (), True, float("inf"))
    todo = _initial_clusters(fleet, config)
    settled: list[_Settled] = []
    rollouts, merges, round_ = 0, 0, 0
    while todo:
        budget = config.budget if round_ <= config.merge_rounds else 0
        searches = [ClusterSearch(fleet, c, config, seeds, budget) for c, seeds in todo]
        _drive(fleet, searches, config)
        rollouts += sum(s.rollouts for s in searches)
        settled += _settle(fleet, searches)
        groups = _merge(fleet, settled, config)
        if not groups:
            break
        merges += len(groups)
        regrouped = [_regroup(fleet, settled, g, config) for g in groups]
        gone = {c for g in groups for c in g}
        settled = [s for c, s in enumerate(settled) if c not in gone]
        todo = [(cluster, [seed]) for cluster, seed in regrouped]
        round_ += 1
    settled.sort(key=lambda s: s.cluster.movers[0])
    decisions = _decisions(fleet, settled, config)
    waiting = sum(d.hold for d in decisions)
    plan_min = min((s.best.min_separation for s in settled), default=float("inf"))
    min_sep = min(plan_min, fleet.lead_min_separation)
    safe = all(s.best.safe for s in settled) and fleet.lead_min_separation >= fleet.separation
    notes = [
        f"clusters: {sorted((len(s.cluster.movers) for s in settled), reverse=True)}",
    ]
    if merges:
        notes.append(f"merged {merges} time(s) after checking the chosen plans")
    if fleet.lead_min_separation < fleet.separation:
        notes.append(
            f"lead-in: robots under way come within {fleet.lead_min_separation:.2f} m before "
            "the plan reaches them"
        )
    return Plan(
        snapshot_version=snapshot.version,
        decisions=tuple(decisions),
        safe=safe,
        min_separation_m=min_sep,
        rollouts=rollouts,
        clusters=len(settled),
        waiting=waiting,
        notes=tuple(notes),
        corridor_radius_m=config.corridor_radius_m,
        corridor_slack_s=config.corridor_slack_s,
        replan_in_s=config.hold_retry_s if waiting else None,
    )


__all__ = ["PlannerConfig", "plan"]
