"""``parkfleet bench fleet``: multi-robot scenarios through the service and sim agents."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from fleet.bench.fleet import POLICIES, FleetBenchRow, default_scenarios, run_fleet_bench
from fleet.cli.options import add_json, add_time_scale
from fleet.cli.signals import interrupt_on_sigterm


def register(commands: Any, bench: Any) -> None:
    p = bench.add_parser(
        "fleet",
        help="swap / random-yard / case III scenarios over Zenoh, four direction policies",
        description="Runs each scenario through a real FleetService (SQLite store, Zenoh) "
        "and time-scaled `parkfleet sim` robots, under the policies auto, cw, ccw and none "
        "(K_avoid = 0), and prints success rate, collisions, minimum separation, makespan "
        "(simulated seconds) and path ratio.",
    )
    add_json(p)
    p.add_argument("--quick", action="store_true", help="fewer scenarios (swap 2, 4; one yard)")
    add_time_scale(p, default=5.0)
    p.add_argument(
        "--horizon", type=float, default=120.0, help="simulated seconds per task before timeout"
    )
    p.add_argument(
        "--policy", action="append", choices=POLICIES, help="only these policies (repeatable)"
    )
    p.add_argument("--scenario", action="append", help="only scenarios with these names")
    p.set_defaults(func=run)


def _print_row(row: FleetBenchRow) -> None:
    print(
        f"{row.scenario:<10} {row.robots:>3} {row.policy:<5} {row.success_rate:>8.0%} "
        f"{row.collisions:>10} {row.min_separation_m:>9.3f} {row.makespan_s:>10.1f} "
        f"{row.path_ratio:>6.2f}",
        flush=True,
    )


def run(args: argparse.Namespace) -> int:
    with interrupt_on_sigterm():  # unwind, so every sim subprocess and session is closed
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    scenarios = default_scenarios(quick=args.quick)
    if args.scenario:
        scenarios = [s for s in scenarios if s.name in set(args.scenario)]
        if not scenarios:
            raise ValueError(f"no scenario named {args.scenario}")
    policies = tuple(args.policy) if args.policy else POLICIES
    if not args.json:
        print(
            f"{'scenario':<10} {'N':>3} {'policy':<5} {'success':>8} {'collisions':>10} "
            f"{'min sep m':>9} {'makespan s':>10} {'path':>6}",
            flush=True,
        )
    rows = run_fleet_bench(
        scenarios,
        policies,
        time_scale=args.time_scale,
        horizon_s=args.horizon,
        progress=None if args.json else _print_row,
    )
    if args.json:
        json.dump({"rows": [r.model_dump() for r in rows]}, sys.stdout)
        print()
    return 0
