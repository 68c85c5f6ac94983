"""Planner latency per decision, and plan quality against fixed laws, offline.

**Latency.** For each fleet size (10, 20, 50 robots) and seed, a random yard at constant
density (10 robots per 100 m^2, :func:`fleet.bench.closed_loop.yard`): half of the tasks
arrive at once, the other half as a Poisson stream while the first half drives; the
offline fleet (:mod:`fleet.bench.closed_loop`) calls :func:`fleet.core.planner.plan` as the
service does (tasks arriving or finishing, a robot leaving its corridor, held robots,
every ``REPLAN_PERIOD_S``), so decisions mix new tasks and robots under way, until
``AFTER_LAST_ARRIVAL_S`` after the last task arrived. Per
decision: wall time, CPU time of this process (both cores when the simulator runs in
parallel), rollouts and clusters. Reported per size: p50/p99 of both times, rollouts
p50/max, clusters mean/max, and how the run went (success, collisions, closest approach).

**Quality** (``--quality``). Antipodal swaps (both chiralities) and random yards, run to
the end under ``auto`` (the planner) and the fixed laws ``cw`` and ``ccw`` (same
assignment, every robot at once, the robots' own avoidance only): success, collisions,
minimum separation, makespan and path ratio, as the fleet benchmark defines them. The
robots are the batch simulator's: no noise, no latency (``parkfleet bench fleet`` adds
those, through the real service).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel

from fleet.bench.closed_loop import arrival_times, run_closed_loop, yard
from fleet.bench.metrics import percentile
from fleet.bench.scenarios import Scenario, swap
from fleet.core.planner import Plan, PlanningSnapshot, plan

ROBOT_COUNTS: tuple[int, ...] = (10, 20, 50)
SEEDS: tuple[int, ...] = (1, 2, 3)
#: Mean gap [s] between streamed tasks.
STREAM_GAP_S = 4.0
#: [s] the planner is also called this often (besides its triggers).
REPLAN_PERIOD_S = 5.0
#: [s, simulated] a run goes on this long after its last task arrived (a fixed limit cut the
#: stream of 200 robots short: its last task arrives after ~400 s).
AFTER_LAST_ARRIVAL_S = 180.0
#: The issue's targets: p99 wall time per decision [ms] by fleet size.
TARGET_P99_MS = {10: 100.0, 50: 1000.0, 200: 1000.0}
POLICIES: tuple[str, ...] = ("auto", "cw", "ccw")


class LatencyRow(BaseModel):
    """Planner decisions on the yards of one size."""

    robots: int
    seeds: int
    decisions: int
    plan_p50_ms: float
    plan_p99_ms: float
    cpu_p50_ms: float
    cpu_p99_ms: float
    rollouts_p50: float
    rollouts_max: int
    clusters_mean: float
    clusters_max: int
    success_rate: float
    collisions: int
    min_separation_m: float


@dataclass
class _Timed:
    """:func:`plan` with its wall and CPU time recorded per call."""

    wall: list[float]
    cpu: list[float]

    def __call__(self, snapshot: PlanningSnapshot) -> Plan:
        w, c = time.perf_counter(), time.process_time()
        result = plan(snapshot)
        self.cpu.append(time.process_time() - c)
        self.wall.append(time.perf_counter() - w)
        return result


def arrivals(n: int, seed: int) -> list[float]:
    """Half the tasks at 0 s, the rest streamed (mean gap ``STREAM_GAP_S``)."""
    first = n // 2
    rest = arrival_times(n - first + 1, seed, STREAM_GAP_S)[1:]
    return [0.0] * first + rest


def latency(robots: int, seeds: Sequence[int]) -> LatencyRow:
    """Decisions on ``seeds`` yards of ``robots`` robots (see the module docstring)."""
    timed = _Timed([], [])
    rollouts: list[int] = []
    clusters: list[int] = []
    success, collisions, closest = [], 0, math.inf
    for seed in seeds:
        scenario = yard(robots, seed)
        times = arrivals(robots, seed)
        run = run_closed_loop(
            scenario,
            "auto",
            timed,
            arrivals=times,
            replan_period_s=REPLAN_PERIOD_S,
            time_limit_s=max(times) + AFTER_LAST_ARRIVAL_S,
        )
        rollouts += run.plan_rollouts
        clusters += run.plan_clusters
        success.append(run.success_rate)
        collisions += run.collisions
        closest = min(closest, run.min_separation_m)
    ms = 1e3
    return LatencyRow(
        robots=robots,
        seeds=len(seeds),
        decisions=len(timed.wall),
        plan_p50_ms=round(percentile(timed.wall, 50) * ms, 1),
        plan_p99_ms=round(percentile(timed.wall, 99) * ms, 1),
        cpu_p50_ms=round(percentile(timed.cpu, 50) * ms, 1),
        cpu_p99_ms=round(percentile(timed.cpu, 99) * ms, 1),
        rollouts_p50=float(np.median(rollouts)) if rollouts else 0.0,
        rollouts_max=max(rollouts, default=0),
        clusters_mean=round(float(np.mean(clusters)), 2) if clusters else 0.0,
        clusters_max=max(clusters, default=0),
        success_rate=round(float(np.mean(success)), 3),
        collisions=collisions,
        min_separation_m=round(closest, 3),
    )


class QualityRow(BaseModel):
    """One scenario under one policy in the offline fleet."""

    scenario: str
    robots: int
    policy: str
    success_rate: float
    collisions: int
    min_separation_m: float
    makespan_s: float
    path_ratio: float | None  # over the tasks that arrived; None: none did


def quality_scenarios(quick: bool = False) -> list[Scenario]:
    """Swaps of 2..16 in both chiralities and yards of 10 and 20 robots."""
    if quick:
        return [swap(2, "right"), swap(2, "left")]
    swaps = [swap(n, chirality) for n in (2, 4, 8, 16) for chirality in ("right", "left")]
    yards = [yard(10, seed) for seed in range(1, 7)] + [yard(20, seed) for seed in (1, 2)]
    return [*swaps, *yards]


def quality(
    scenarios: Sequence[Scenario],
    policies: Sequence[str] = POLICIES,
    progress: Callable[[QualityRow], None] | None = None,
) -> list[QualityRow]:
    rows = []
    for scenario in scenarios:
        for policy in policies:
            run = run_closed_loop(
                scenario,
                policy,
                plan if policy == "auto" else None,
                replan_period_s=REPLAN_PERIOD_S,
            )
            row = QualityRow(
                scenario=scenario.name,
                robots=run.robots,
                policy=policy,
                success_rate=run.success_rate,
                collisions=run.collisions,
                min_separation_m=round(run.min_separation_m, 3),
                makespan_s=round(run.makespan_s, 2),
                path_ratio=None if math.isnan(run.path_ratio) else round(run.path_ratio, 3),
            )
            rows.append(row)
            if progress is not None:
                progress(row)
    return rows


__all__ = [
    "POLICIES",
    "REPLAN_PERIOD_S",
    "ROBOT_COUNTS",
    "SEEDS",
    "TARGET_P99_MS",
    "LatencyRow",
    "QualityRow",
    "arrivals",
    "latency",
    "quality",
    "quality_scenarios",
]
