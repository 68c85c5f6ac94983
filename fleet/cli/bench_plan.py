"""``parkfleet bench plan``: planner latency per decision (and, offline, plan quality)."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING, Any

from fleet.cli.options import add_json

if TYPE_CHECKING:
    from fleet.bench.plan import QualityRow


def register(commands: Any, bench: Any) -> None:
    p = bench.add_parser(
        "plan",
        help="planner latency per decision on 10/20/50-robot yards (p50/p99, rollouts, "
        "clusters); --quality: auto vs fixed laws, offline",
        description="Runs random yards of 10, 20 and 50 robots (several seeds; half the "
        "tasks at once, the rest streamed while the first half drives) in the offline "
        "fleet, calling the planner as the service does, and prints per fleet size the "
        "p50/p99 wall and CPU time per decision, rollouts and clusters. --quality also "
        "runs swaps (both chiralities) and yards to the end under auto, cw and ccw.",
    )
    add_json(p)
    p.add_argument(
        "--robots", type=int, nargs="+", metavar="N", help="fleet sizes (default 10 20 50)"
    )
    p.add_argument("--seeds", type=int, default=3, help="yards per size (default 3)")
    p.add_argument("--quality", action="store_true", help="also compare auto with cw/ccw, offline")
    p.add_argument("--quick", action="store_true", help="4 robots, one seed (smoke test)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.plan import ROBOT_COUNTS, TARGET_P99_MS, latency, quality, quality_scenarios

    sizes = [4] if args.quick else (args.robots or list(ROBOT_COUNTS))
    seeds = list(range(1, 2 if args.quick else args.seeds + 1))
    if any(n < 1 for n in sizes) or not seeds:
        raise ValueError("--robots and --seeds must be at least 1")
    if not args.json:
        print(
            f"{'robots':>6} {'decisions':>9} {'p50 ms':>8} {'p99 ms':>8} {'cpu p50':>8} "
            f"{'cpu p99':>8} {'rollouts':>9} {'clusters':>9} {'success':>8} {'min sep':>8}",
            flush=True,
        )
    rows = []
    for n in sizes:
        row = latency(n, seeds)
        rows.append(row)
        if not args.json:
            target = TARGET_P99_MS.get(n)
            print(
                f"{row.robots:>6} {row.decisions:>9} {row.plan_p50_ms:>8.1f} "
                f"{row.plan_p99_ms:>8.1f} {row.cpu_p50_ms:>8.1f} {row.cpu_p99_ms:>8.1f} "
                f"{row.rollouts_p50:>4.0f}/{row.rollouts_max:<4} "
                f"{row.clusters_mean:>4.1f}/{row.clusters_max:<4} {row.success_rate:>8.0%} "
                f"{row.min_separation_m:>8.3f}"
                + (f"   target p99 <= {target:.0f} ms" if target else ""),
                flush=True,
            )
    report: dict[str, list[dict[str, Any]]] = {"latency": [r.model_dump() for r in rows]}
    if args.quality:
        if not args.json:
            print(
                f"\n{'scenario':<14} {'N':>3} {'policy':<5} {'success':>8} {'collisions':>10} "
                f"{'min sep m':>9} {'makespan s':>10} {'path':>6}"
            )
        quality_rows = quality(
            quality_scenarios(args.quick), progress=None if args.json else print_row
        )
        report["quality"] = [r.model_dump() for r in quality_rows]
    if args.json:
        print(json.dumps(report))
    else:
        print("wall and CPU time per planner decision (CPU: this process, all threads)")
    return 0


def print_row(row: QualityRow) -> None:
    """One quality row, aligned with the header ``run`` prints."""
    print(
        f"{row.scenario:<14} {row.robots:>3} {row.policy:<5} {row.success_rate:>8.0%} "
        f"{row.collisions:>10} {row.min_separation_m:>9.3f} {row.makespan_s:>10.1f} "
        f"{'-' if row.path_ratio is None else f'{row.path_ratio:.2f}':>6}",
        flush=True,
    )
