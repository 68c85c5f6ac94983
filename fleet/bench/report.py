"""Tables of a ``parkfleet bench fleet`` run: every policy side by side, and ``auto``'s verdict.

Pure formatting of :class:`~fleet.bench.fleet.FleetBenchRow` lists (one run's rows, or the
``rows`` of its ``--json`` output) as Markdown, for docs/benchmarks.md:

* :func:`policy_table` -- one line per scenario family, one column per policy; a cell is
  ``success · collisions · makespan`` (means over the family's seeds; with several seeds
  the worst success and the most collisions follow in brackets), then the robots that hit
  a static obstacle in the worst run, if any;
* :func:`auto_table` -- ``auto`` against the issue's targets, family by family: 100 %
  success and 0 collisions (with robots or obstacles), success at least every navground
  behaviour's, makespan within 1.25x of the fastest policy that touched nothing (and, for
  reference, its path ratio, deadlocks, worst separation and planning latency). Misses are
  spelled out;
* :func:`smoothness_table` -- families x policies, ``stops / cusps`` per trip (means over
  seeds; definitions in :mod:`fleet.bench.metrics`);
* :func:`planning_wait_table` -- for the fleet policies, how much of a makespan is waiting
  for the service, which the time scale inflates: the robots run S times faster than the
  wall clock while the planner takes wall time, so a plan of p wall seconds holds a robot
  waiting for it S x p simulated seconds. The bench does not remove this distortion (the
  service plans in real time; pausing the robots' clock for it would hide what a user
  waits); it measures it: the wait of the task that arrived last, from its submission to
  its robot leaving idle (the makespan shrinks by at most this at time scale 1 -- minus the
  wall time the plan still takes), and every plan's wall time x S;
* :func:`law_alone_table` -- ``auto``'s makespan beside the makespan its robots would have
  alone under the paper's faster law (``law_solo_s``, :mod:`fleet.bench.solo_floor`, an
  estimate on the peers' goals) and the fastest collision-free policy's: when the law alone
  already needs more than 1.25x the fastest policy, meeting the makespan target takes a
  plan that beats the law's own solo drive; ``auto / law alone`` is what the fleet's
  interactions and the disturbances add. Only for runs that carry the estimate.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet.bench.fleet import PEER_POLICIES, FleetBenchRow, SummaryRow, summarise

#: auto's makespan may be this many times the fastest collision-free policy's (issue 12).
MAKESPAN_FACTOR = 1.25


def _families(rows: Sequence[FleetBenchRow]) -> list[str]:
    return list(dict.fromkeys(r.family for r in rows))


def _policies(rows: Sequence[FleetBenchRow]) -> list[str]:
    return list(dict.fromkeys(r.policy for r in rows))


def _cell(s: SummaryRow | None) -> str:
    if s is None:
        return ""
    text = f"{s.success_mean:.0%} · {s.collisions_mean:g} · {s.makespan_mean_s:.0f} s"
    if s.runs > 1:
        text = (
            f"{s.success_mean:.0%} ({s.success_worst:.0%}) · {s.collisions_mean:g} "
            f"({s.collisions_worst}) · {s.makespan_mean_s:.0f} s"
        )
    if s.obstacle_hits_worst:
        hits = s.obstacle_hits_worst
        text += f" · **{hits} robot{'s' if hits > 1 else ''} hit obstacles**"
    return text


def policy_table(rows: Sequence[FleetBenchRow]) -> str:
    """Markdown: families x policies, ``success · collisions · makespan`` per cell."""
    summary = {(s.family, s.policy): s for s in summarise(rows)}
    policies = _policies(rows)
    lines = [
        "| scenario | N | runs | " + " | ".join(policies) + " |",
        "|---|---|---|" + "---|" * len(policies),
    ]
    for family in _families(rows):
        first = next(s for (f, _), s in summary.items() if f == family)
        cells = [_cell(summary.get((family, p))) for p in policies]
        lines.append(f"| {family} | {first.robots} | {first.runs} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _fastest_clean(family: str, summary: dict[tuple[str, str], SummaryRow]) -> SummaryRow | None:
    """The other policy that parked every task and touched no robot and no obstacle in any
    run, with the shortest mean makespan (a policy that failed a task is no yardstick: its
    makespan is the time limit, or it stood still and touched nothing)."""
    clean = [
        s
        for (f, p), s in summary.items()
        if f == family
        and p != "auto"
        and s.success_worst >= 1.0
        and s.collisions_worst == 0
        and s.obstacle_hits_worst == 0
    ]
    return min(clean, key=lambda s: s.makespan_mean_s, default=None)


def _misses(auto: SummaryRow, family: str, summary: dict[tuple[str, str], SummaryRow]) -> list[str]:
    misses = []
    if auto.success_worst < 1.0:
        misses.append(f"success {auto.success_worst:.0%}")
    if auto.collisions_worst:
        pairs = auto.collisions_worst
        misses.append(f"{pairs} colliding pair{'s' if pairs > 1 else ''}")
    if auto.obstacle_hits_worst:
        hits = auto.obstacle_hits_worst
        misses.append(f"{hits} robot{'s' if hits > 1 else ''} hit obstacles")
    better = [
        p
        for p in PEER_POLICIES
        if (peer := summary.get((family, p))) is not None and peer.success_mean > auto.success_mean
    ]
    if better:
        misses.append("less success than " + ", ".join(better))
    best = _fastest_clean(family, summary)
    if best is not None and auto.makespan_mean_s > MAKESPAN_FACTOR * best.makespan_mean_s:
        misses.append(
            f"makespan {auto.makespan_mean_s / best.makespan_mean_s:.1f}x {best.policy}'s"
        )
    return misses


def _ratio(mean: float, worst: float, runs: int) -> str:
    return f"{mean:.0%} ({worst:.0%})" if runs > 1 else f"{mean:.0%}"


def auto_table(rows: Sequence[FleetBenchRow]) -> str:
    """Markdown: ``auto`` per family against the targets, misses spelled out."""
    summary = {(s.family, s.policy): s for s in summarise(rows)}
    lines = [
        "| scenario | success mean (worst) | collisions (worst run) | min sep worst [m] | "
        "makespan [s] | fastest collision-free | path ratio | deadlocks | "
        "plan p50 / p99 [ms] | targets missed |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for family in _families(rows):
        auto = summary.get((family, "auto"))
        if auto is None:
            continue
        best = _fastest_clean(family, summary)
        plans = [r for r in rows if r.family == family and r.policy == "auto"]
        p50 = [r.plan_p50_ms for r in plans if r.plan_p50_ms is not None]
        p99 = [r.plan_p99_ms for r in plans if r.plan_p99_ms is not None]
        plan = f"{np.median(p50):.0f} / {max(p99):.0f}" if p50 and p99 else "-"
        sep = "-" if auto.min_separation_worst_m is None else f"{auto.min_separation_worst_m:.2f}"
        fastest = "-" if best is None else f"{best.policy} {best.makespan_mean_s:.0f} s"
        ratio = "-" if auto.path_ratio_mean is None else f"{auto.path_ratio_mean:.2f}"
        misses = _misses(auto, family, summary)
        lines.append(
            f"| {family} | {_ratio(auto.success_mean, auto.success_worst, auto.runs)} | "
            f"{auto.collisions_mean:g} ({auto.collisions_worst}) | {sep} | "
            f"{auto.makespan_mean_s:.0f} | {fastest} | {ratio} | {auto.deadlocks_mean:g} | "
            f"{plan} | {'; '.join(misses) or 'none'} |"
        )
    return "\n".join(lines)


def smoothness_table(rows: Sequence[FleetBenchRow]) -> str:
    """Markdown: families x policies, ``stops / cusps`` per trip (means over the seeds)."""
    summary = {(s.family, s.policy): s for s in summarise(rows)}
    policies = _policies(rows)
    lines = [
        "| scenario (stops / cusps per trip) | " + " | ".join(policies) + " |",
        "|---|" + "---|" * len(policies),
    ]
    for family in _families(rows):
        cells = []
        for policy in policies:
            s = summary.get((family, policy))
            stops = None if s is None else s.stops_mean
            cusps = None if s is None else s.cusps_mean
            cells.append("" if stops is None or cusps is None else f"{stops:.1f} / {cusps:.1f}")
        lines.append(f"| {family} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def planning_wait_table(rows: Sequence[FleetBenchRow]) -> str:
    """Markdown: per family and fleet policy, the makespan, the last-arriving task's wait
    for the service and its share of the makespan, and the plans' wall time x time scale."""
    summary = {(s.family, s.policy): s for s in summarise(rows)}
    scales = sorted({r.time_scale for r in rows if r.time_scale is not None})
    scale = "S" if len(scales) != 1 else f"{scales[0]:g}"
    lines = [
        f"| scenario | policy | makespan [s] | last task's wait for the service [s] | "
        f"share of makespan | plans' wall time x {scale} [s] |",
        "|---|---|---|---|---|---|",
    ]
    for (family, policy), s in summary.items():
        if s.plan_wait_mean_s is None and s.planning_sim_mean_s is None:
            continue  # navground: no service
        wait = "-" if s.plan_wait_mean_s is None else f"{s.plan_wait_mean_s:.1f}"
        share = (
            "-"
            if s.plan_wait_mean_s is None or not s.makespan_mean_s
            else f"{s.plan_wait_mean_s / s.makespan_mean_s:.0%}"
        )
        planning = "-" if s.planning_sim_mean_s is None else f"{s.planning_sim_mean_s:.1f}"
        lines.append(
            f"| {family} | {policy} | {s.makespan_mean_s:.1f} | {wait} | {share} | {planning} |"
        )
    return "\n".join(lines)


def law_alone_table(rows: Sequence[FleetBenchRow]) -> str:
    """Markdown: per family, ``auto``'s mean makespan, the law alone (module docstring), the
    fastest collision-free policy's, and the ratios of the law alone to the fastest and of
    auto to the law alone; empty when no ``auto`` row carries the estimate (older runs)."""
    summary = {(s.family, s.policy): s for s in summarise(rows)}
    lines = [
        "| scenario | auto makespan [s] | the law alone [s] | fastest collision-free [s] | "
        "law alone / fastest | auto / law alone |",
        "|---|---|---|---|---|---|",
    ]
    for family in _families(rows):
        auto = summary.get((family, "auto"))
        floors = [
            r.law_solo_s
            for r in rows
            if r.family == family and r.policy == "auto" and r.law_solo_s is not None
        ]
        if auto is None or not floors:
            continue
        floor = float(np.mean(floors))
        best = _fastest_clean(family, summary)
        fastest = "-" if best is None else f"{best.policy} {best.makespan_mean_s:.1f}"
        share = "-" if best is None else f"{floor / best.makespan_mean_s:.2f}x"
        lines.append(
            f"| {family} | {auto.makespan_mean_s:.1f} | {floor:.1f} | {fastest} | {share} | "
            f"{auto.makespan_mean_s / floor:.2f}x |"
        )
    return "\n".join(lines) if len(lines) > 2 else ""
