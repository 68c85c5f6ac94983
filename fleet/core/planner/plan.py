"""``plan``: who takes which task, with which law, when -- and who waits (pure).

1. **Assignment** (:mod:`~fleet.core.planner.assign`): queued tasks get available robots
   (a pair whose every way passes a robot standing there is tried with another robot).
2. **Scene** (:mod:`~fleet.core.planner.scene`): the robots to decide (new, under way,
   held), the standing robots, the lead-in until the plan reaches the robots, each
   mover's solo predictions, and the single-robot zones each mover's way enters: a robot
   whose zone another holds or takes first holds in every candidate below
   (:mod:`~fleet.core.planner.gates`).
3. **Seed and clusters**: a prioritised plan on the solo predictions staggers the robots
   (:mod:`~fleet.core.planner.reserve`, no simulation); robots whose staggered paths come
   within the peer radius (+ a margin) of each other at about the same time while both
   move are searched together, the others apart (:mod:`~fleet.core.planner.clusters`).
   Standing robots (lost ones too) join only the clusters that pass near them, and a robot
   waiting at its start or parked at its goal where another cluster passes is a standing
   obstacle ("phantom") of that cluster.
4. **Search** (:mod:`~fleet.core.planner.search`): per cluster a law, a start delay or a
   hold for every robot, by closed-loop rollouts at the agents' step; every cluster's
   round goes to the simulator together (:mod:`~fleet.core.planner.rollout`).
5. **Check**: the chosen plans' recorded rollouts are checked against each other. Clusters
   whose robots now meet while both move are merged, and a cluster that passes a robot
   of another standing where it did not know, or a standing robot it did not know, gets
   it; those are searched again, seeded with their plans -- repairing conflicts only,
   within ``recheck_budget``, ``merge_rounds`` times, then with the baseline and the safety
   net only, and after that whatever still meets is merged -- until no plan meets what its
   cluster did not see.
6. **Verify**: one rollout of the whole fleet -- every mover with its chosen option, every
   standing robot, no phantoms -- is exactly what the robots will do (phantoms stand for a
   robot of another cluster during the whole rollout, so a cluster's own prediction is
   conservative, not exact). Its recording gives the corridors, arrivals and separations the
   decisions carry. Should it bring a pair closer than ``separation_m``, the robots it would
   start or keep moving into that pair hold (new ones first) and the fleet is verified
   again, ``verify_rounds`` times at most.
7. **Standstill**: when that holds every robot it decides (none would move, so nothing
   would ever change: a swap whose goals are the others' starts, robots pressed together by
   disturbances), the plan is made again keeping contact distance (two body radii) plus
   ``standstill_margin_m`` (0.42 m by default) instead of ``separation_m``, and taken if it
   moves someone (noted in ``Plan.notes``). Robots whose every way comes closer than that
   still wait, with the reason.
8. **Open approaches**: steps 2-6 run without them first. When a new robot that drives
   straight would, alone, arrive through a via-point on its goal's axis
   (:class:`PlannerConfig`) more than ``open_approach_gain_s`` before that plan brings it,
   they run again with the points, their rollouts ending shortly after the first plan's
   makespan; the fleet takes the plan with points only if its whole rollout costs less
   (:attr:`~fleet.core.planner.cost.Score.key`) and brings every robot to its goal.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.planner.assign import pair_queued
from fleet.core.planner.clusters import (
    Cluster,
    Phantom,
    clusters,
    components,
    encounters,
    near_standing,
)
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.corridor import sample_corridor
from fleet.core.planner.cost import Limits, Score, score
from fleet.core.planner.model import Action, Plan, PlanningSnapshot, TaskDecision
from fleet.core.planner.reserve import reservation
from fleet.core.planner.rollout import Live, Outcome, advance, roll_out
from fleet.core.planner.scene import (
    NEW,
    Candidate,
    Fleet,
    build_fleet,
    row_names,
    scene_rows,
    stuck,
)
from fleet.core.planner.search import ClusterSearch
from fleet.core.types import LAWS, BoolArray, FloatArray
from fleet.core.zones import ZonePass

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
                rows = scene_rows(fleet, s.cluster, c)
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
    """Why each held robot of the chosen plan holds: the zone it waits for, or the closest
    call of its best release."""
    best = search.best
    assert best is not None
    out: dict[int, str] = {}
    ids = row_names(fleet, search.cluster)
    for pos in (int(v) for v in np.flatnonzero(best.candidate.hold)):
        zone_reason = (
            fleet.gates.reasons[search.cluster.movers[pos]] if fleet.gates.reasons else None
        )
        if zone_reason is not None:
            out[pos] = zone_reason
            continue
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


def _moving(o: Outcome, c: Candidate, k: int) -> tuple[FloatArray, BoolArray]:
    """Positions (T, k, 2) of a rollout's movers and where each moves (T, k)."""
    assert o.xy is not None and o.times is not None
    arrival = np.where(np.isnan(o.time[:k]), np.inf, o.time[:k])
    t = o.times[:, None]
    return o.xy[:, :k], (~c.hold[None, :]) & (t >= c.delay[None, :]) & (t < arrival[None, :])


def _paths(fleet: Fleet, settled: Sequence[_Settled]) -> tuple[FloatArray, BoolArray]:
    """Every mover's recorded positions on one time grid (k, T, 2), padded with the last,
    and where each moves (k, T)."""
    k = fleet.movers.size
    length = max((s.outcome.xy.shape[0] for s in settled if s.outcome.xy is not None), default=1)
    paths = np.zeros((k, length, 2))
    moving = np.zeros((k, length), dtype=bool)
    for s in settled:
        xy, mov = _moving(s.outcome, s.best.candidate, len(s.cluster.movers))
        n = xy.shape[0]
        for pos, i in enumerate(s.cluster.movers):
            paths[i, :n], paths[i, n:] = xy[:, pos], xy[-1, pos]
            moving[i, :n] = mov[:, pos]
    return paths, moving


@dataclass(frozen=True)
class _Redo:
    """Settled clusters to search again as one, with what they did not see."""

    group: list[int]
    phantoms: set[Phantom]
    standing: set[int]


def _check(fleet: Fleet, settled: Sequence[_Settled], force: bool) -> list[_Redo]:
    """What the chosen plans meet that their clusters did not see (module docstring, 5).

    ``force``: a cluster that missed a robot of another cluster is merged with it."""
    k = fleet.movers.size
    paths, moving = _paths(fleet, settled)
    where = np.zeros(k, dtype=np.int64)
    for c, s in enumerate(settled):
        where[list(s.cluster.movers)] = c
    reach = max(fleet.world.avoidance.peer_radius, fleet.separation) + _CHECK_MARGIN
    found = encounters(paths, moving, list(range(k)), reach, 1)
    links = [(int(where[i]), int(where[j])) for i, j in found.pairs if where[i] != where[j]]
    ghosts: dict[int, set[Phantom]] = {}
    for i, wanted in found.phantoms.items():
        c = int(where[i])
        for p in wanted:
            if where[p[2]] != c and not settled[c].cluster.knows(p):
                if force:
                    links.append((c, int(where[p[2]])))
                else:
                    ghosts.setdefault(c, set()).add(p)
    stand: dict[int, set[int]] = {}
    live = np.flatnonzero(moving.any(axis=1))
    for i, j in near_standing(paths[live], live.tolist(), fleet.standing_xy, reach):
        c = int(where[i])
        if j not in settled[c].cluster.standing:
            stand.setdefault(c, set()).add(j)
    touched = {c for pair in links for c in pair} | set(ghosts) | set(stand)
    out = []
    for group in components(len(settled), links):
        if any(c in touched for c in group):
            out.append(
                _Redo(
                    group,
                    set().union(*(ghosts.get(c, set()) for c in group)),
                    set().union(*(stand.get(c, set()) for c in group)),
                )
            )
    return out


def _regroup(fleet: Fleet, settled: Sequence[_Settled], redo: _Redo) -> tuple[Cluster, Candidate]:
    """One cluster for ``redo`` and the seed its clusters' plans make."""
    parts = [settled[c] for c in redo.group]
    movers = sorted(i for s in parts for i in s.cluster.movers)
    members = set(movers)
    standing = sorted(redo.standing.union(*(s.cluster.standing for s in parts)))
    ghosts = {p for s in parts for p in s.cluster.phantoms if p[2] not in members}
    ghosts |= {p for p in redo.phantoms if p[2] not in members}
    seed = fleet.keep(movers)
    for s in parts:
        cand = s.best.candidate
        for pos, i in enumerate(s.cluster.movers):
            j = movers.index(i)
            seed.law[j], seed.delay[j], seed.hold[j] = (
                cand.law[pos],
                cand.delay[pos],
                cand.hold[pos],
            )
    return Cluster(tuple(movers), tuple(standing), tuple(sorted(ghosts))), seed


def _initial_clusters(fleet: Fleet, config: PlannerConfig) -> list[tuple[Cluster, list[Candidate]]]:
    """Clusters of the prioritised seed's paths, each with its share of the seed."""
    m = fleet.movers
    k = m.size
    sep = fleet.separation
    seed, paths = reservation(
        fleet,
        list(range(k)),
        list(range(fleet.standing_xy.shape[0])),
        config.reserve_delays_s,
        sep + config.reserve_margin_m,
        sep + config.reserve_margin_m / 2,
    )
    period = fleet.solo_times[1] - fleet.solo_times[0] if fleet.solo_times.size > 1 else 1.0
    t = np.arange(paths.shape[1])[None, :] * period
    solo = fleet.solo_time[np.arange(k), seed.law]
    moving = (t >= seed.delay[:, None]) & (t < (seed.delay + solo)[:, None])
    reach = fleet.world.avoidance.peer_radius + config.interaction_margin_m
    window = max(1, round(config.cluster_slack_s / period))
    out = []
    for c in clusters(paths, moving, k, fleet.standing_xy, reach, window):
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
            arrival = s.best.arrival[pos] if o.done[pos] else math.nan
            # the corridor ends where the robot stops: where it holds, or at its arrival
            # (then it stands at its final pose), else at the end of the rollout
            times, xy = o.times, o.xy[:, pos]
            if hold:
                times, xy = times[:1], xy[:1]
            elif o.done[pos]:
                before = int(np.searchsorted(times, float(o.time[pos]) - 1e-9))
                times = np.append(times[:before], o.time[pos])
                xy = np.vstack([xy[:before], o.final[pos, :2]])
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
                    corridor=sample_corridor(times, xy, every),
                    predicted_min_separation_m=float(s.best.separation[pos]),
                    route=tuple((float(x), float(y)) for x, y in m.route[i]) if m.route else (),
                    last_leg=bool(m.last_leg[i]) if m.last_leg.size else False,
                    pass_m=fleet.world.pass_m,
                    zones=() if hold else _granted(fleet, i),
                    waits_for=_waits_for(fleet, i) if hold else None,
                )
            )
    return out


def _granted(fleet: Fleet, i: int) -> tuple[ZonePass, ...]:
    """The passes through single-robot zones mover ``i`` holds when it moves."""
    granted = fleet.gates.granted
    return granted[i] if i < len(granted) else ()


def _waits_for(fleet: Fleet, i: int) -> str | None:
    """The single-robot zone mover ``i`` waits for, if it holds for one."""
    waits = fleet.gates.waits_for
    return waits[i] if i < len(waits) else None


def _whole(fleet: Fleet, settled: Sequence[_Settled]) -> tuple[Candidate, dict[int, str]]:
    """The clusters' chosen options as one candidate over every mover, and their hold
    reasons by mover index."""
    k = fleet.movers.size
    cand = fleet.keep(range(k))
    reasons: dict[int, str] = {}
    for s in settled:
        c = s.best.candidate
        for pos, i in enumerate(s.cluster.movers):
            cand.law[i], cand.delay[i], cand.hold[i] = c.law[pos], c.delay[pos], c.hold[pos]
            if pos in s.reasons:
                reasons[i] = s.reasons[pos]
    return cand, reasons


def _verify(
    fleet: Fleet, settled: Sequence[_Settled], config: PlannerConfig
) -> tuple[_Settled, int]:
    """The chosen plan rolled out for the whole fleet at once (module docstring, 6): the
    settled whole, and the rollouts it took."""
    k = fleet.movers.size
    cluster = Cluster(tuple(range(k)), tuple(range(fleet.standing_xy.shape[0])))
    cand, reasons = _whole(fleet, settled)
    solo = np.where(np.isfinite(fleet.solo_time), fleet.solo_time, config.max_horizon_s)
    span = max((s.outcome.steps for s in settled), default=0) * fleet.dt
    horizon = min(config.max_horizon_s, span + config.sample_period_s)
    ids = row_names(fleet, cluster)
    kind = fleet.movers.kind
    rounds = 0
    while True:
        rows = scene_rows(fleet, cluster, cand)
        (outcome,) = roll_out(
            [rows],
            fleet.world,
            dt=fleet.dt,
            max_time=horizon,
            record_every=_record_every(fleet, config),
            max_rows=config.max_rows_per_call,
        )
        rounds += 1
        best = score(
            fleet, cluster.movers, cand, rows, outcome, horizon, config.change_penalty_s, solo
        )
        if best.safe or rounds > config.verify_rounds:
            break
        for v in best.violations:  # hold a robot it moves into each conflict (new first)
            moving = [r for r in (v.a, v.b) if r < k and not cand.hold[r]]
            if not moving:
                continue
            r = min(moving, key=lambda i: (kind[i] != NEW, -i))
            other = ids[v.b] if r == v.a else ids[v.a]
            cand.hold[r] = True
            reasons[r] = (
                f"waiting: the whole fleet's rollout brought {other} within "
                f"{v.distance:.2f} m (< {v.allowed:.2f} m) of {ids[r]}"
            )
    return _Settled(cluster, best, outcome, reasons), rounds


def plan(snapshot: PlanningSnapshot, config: PlannerConfig | None = None) -> Plan:
    """Decide the queued and under-way tasks of ``snapshot`` (see the module docstring)."""
    config = config or PlannerConfig()
    strict = _plan(snapshot, config)
    radius = max(
        [snapshot.profile.radius, *(r.profile.radius for r in snapshot.robots if r.profile)]
    )  # the largest body of the fleet
    floor = 2 * radius + config.standstill_margin_m
    if floor >= snapshot.separation_m or not strict.decisions:
        return strict
    if not all(d.hold for d in strict.decisions):
        return strict  # someone moves: the scene changes, the held are tried again
    if all(d.waits_for is not None for d in strict.decisions):
        return strict  # every robot waits for a zone: no margin would move one
    relaxed = _plan(dataclasses.replace(snapshot, separation_m=floor), config)
    if all(d.hold for d in relaxed.decisions):
        return dataclasses.replace(strict, rollouts=strict.rollouts + relaxed.rollouts)
    note = (
        f"standstill: no robot could move keeping {snapshot.separation_m:.2f} m; planned "
        f"keeping {floor:.2f} m (contact + {config.standstill_margin_m} m)"
    )
    return dataclasses.replace(
        relaxed, rollouts=strict.rollouts + relaxed.rollouts, notes=(*relaxed.notes, note)
    )


#: [s] the plan with open approaches is rolled out this long past the plain plan's makespan.
_APPROACH_CAP_MARGIN_S = 1.0


def _plan(snapshot: PlanningSnapshot, config: PlannerConfig) -> Plan:
    """One plan keeping ``snapshot.separation_m``: without open approaches and, when some
    new robot alone would arrive through its approach point more than
    ``open_approach_gain_s`` before the first plan brings it, with them -- the better of
    the two (the whole fleet's cost, :attr:`Score.key`; the plain one on a tie), the second
    only if it brings every robot to its goal within its horizon (a jam at the approach
    points looks no worse there than robots that are merely late). Alone each robot
    arrives sooner by its approach point, but robots that all drive straight at theirs can
    meet where the laws' rotation senses would have taken them round each other. The
    second plan's rollouts end shortly after the first plan's makespan (a later plan
    cannot win)."""
    plain, plain_key, through = _plan_once(snapshot, config, approach=False)
    arrival = {d.robot_id: d.predicted_arrival_s for d in plain.decisions}
    promising = any(
        t + config.open_approach_gain_s < _or_inf(arrival.get(robot))
        for robot, t in through.items()
    )
    if not promising or plain_key is None:
        return plain
    # no cap (inf) while the first plan leaves some robot short of its goal
    cap = max(map(_or_inf, arrival.values()), default=math.inf) + _APPROACH_CAP_MARGIN_S
    capped = dataclasses.replace(
        config, max_horizon_s=min(config.max_horizon_s, cap),
        min_horizon_s=min(config.min_horizon_s, cap),
    )  # fmt: skip
    approached, key, _ = _plan_once(snapshot, capped, approach=True)
    rollouts = plain.rollouts + approached.rollouts
    arrives = all(d.predicted_arrival_s is not None for d in approached.decisions)
    if arrives and key is not None and key < plain_key:
        given = sum(bool(d.route) and d.robot_id in through for d in approached.decisions)
        note = f"open approaches: {given} new robot(s) via a point on their goal's axis"
        return dataclasses.replace(approached, rollouts=rollouts, notes=(*approached.notes, note))
    return dataclasses.replace(plain, rollouts=rollouts)


def _or_inf(arrival: float | None) -> float:
    """A predicted arrival [s], inf for a robot predicted not to arrive."""
    return math.inf if arrival is None else arrival


def _plan_once(
    snapshot: PlanningSnapshot, config: PlannerConfig, approach: bool
) -> tuple[Plan, tuple[float, ...] | None, dict[str, float]]:
    """One plan (``approach``: with the open approach points the scene finds), its whole
    fleet's cost (None without movers) and, by robot, the solo arrival time through its
    approach point [s] of each new robot that has one."""
    pairs = pair_queued(snapshot, config)
    fleet = build_fleet(snapshot, pairs, config, approach)
    avoid = frozenset(
        (t.task_id, fleet.movers.robot_ids[i])
        for i in stuck(fleet)
        if (t := fleet.movers.tasks[i]).named_robot is None
    )
    if avoid:  # another robot may take these tasks (assign's module docstring)
        pairs = pair_queued(snapshot, config, avoid)
        fleet = build_fleet(snapshot, pairs, config, approach)
    if fleet.movers.size == 0:
        return Plan(snapshot.version, (), True, float("inf")), None, {}
    todo = _initial_clusters(fleet, config)
    settled: list[_Settled] = []
    rollouts, merges, round_ = 0, 0, 0
    while todo:
        if round_ == 0:
            budget = config.budget
        else:
            budget = config.recheck_budget if round_ <= config.merge_rounds else 0
        searches = [
            ClusterSearch(fleet, c, config, seeds, budget, improve=round_ == 0) for c, seeds in todo
        ]
        _drive(fleet, searches, config)
        rollouts += sum(s.rollouts for s in searches)
        settled += _settle(fleet, searches)
        redo = _check(fleet, settled, force=round_ > config.merge_rounds + 1)
        if not redo:
            break
        merges += len(redo)
        regrouped = [_regroup(fleet, settled, r) for r in redo]
        gone = {c for r in redo for c in r.group}
        settled = [s for c, s in enumerate(settled) if c not in gone]
        todo = [(cluster, [seed]) for cluster, seed in regrouped]
        round_ += 1
    settled.sort(key=lambda s: s.cluster.movers[0])
    whole, verified = _verify(fleet, settled, config)
    rollouts += verified
    decisions = _decisions(fleet, [whole], config)
    waiting = sum(d.hold for d in decisions)
    min_sep = min(whole.best.min_separation, fleet.lead_min_separation)
    safe = whole.best.safe and fleet.lead_min_separation >= fleet.separation
    notes = [
        f"clusters: {sorted((len(s.cluster.movers) for s in settled), reverse=True)}",
    ]
    if verified > 1:
        notes.append(f"held robots after {verified - 1} whole-fleet check(s) found conflicts")
    if merges:
        notes.append(f"searched {merges} cluster(s) again after checking the chosen plans")
    if fleet.lead_min_separation < fleet.separation:
        notes.append(
            f"lead-in: robots under way come within {fleet.lead_min_separation:.2f} m before "
            "the plan reaches them"
        )
    result = Plan(
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
    through = {
        fleet.movers.robot_ids[i]: float(t)
        for i, t in enumerate(fleet.approach_time)
        if math.isfinite(t)
    }
    return result, whole.best.key, through


__all__ = ["PlannerConfig", "plan"]
