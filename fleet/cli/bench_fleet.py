"""``parkfleet bench fleet``: the fleet and navground's planners on the benchmark scenarios."""

from __future__ import annotations

import argparse
import fnmatch
import json
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from fleet.bench.fleet import (
    DISTURBED_FLAGS,
    POLICIES,
    BenchOptions,
    FleetBenchRow,
    SummaryRow,
    run_fleet_bench,
    summarise,
)
from fleet.bench.report import (
    auto_table,
    law_alone_table,
    planning_wait_table,
    policy_table,
    smoothness_table,
)
from fleet.bench.scenarios import Scenario, full_suite, load_scenarios, quick_suite
from fleet.cli.options import add_json, add_time_scale, positive_float, positive_int
from fleet.io.settings import load_settings
from sim_agent.robots import SimRobots


def register(commands: Any, bench: Any) -> None:
    p = bench.add_parser(
        "fleet",
        help="swaps, random yards, streams, a car park, case III: fleet policies and navground",
        description="Runs each scenario through a real FleetService (SQLite store, Zenoh) and "
        "time-scaled `parkfleet sim` robots with a real robot's disturbances, under the "
        "policies auto, cw, ccw and none (no avoidance), and through navground's ORCA, HRVO, "
        "HL and social force on the same simulated robots (same disturbances, link and seed); "
        "measures success, collisions and minimum "
        "separation on time-aligned true poses, makespan (simulated s), path ratio, "
        "deadlocks and planning latency. Progress goes to stderr with --json.",
    )
    add_json(p)
    p.add_argument("--quick", action="store_true", help="the daily subset (~10 min)")
    p.add_argument(
        "--scenario",
        action="append",
        metavar="PATTERN",
        help="only scenarios whose name matches (glob, e.g. 'swap-*'; repeatable)",
    )
    p.add_argument(
        "--scenario-file",
        action="append",
        type=Path,
        metavar="FILE.json",
        help="run the scenarios of FILE instead of the built-in suite (repeatable; format in "
        "fleet/bench/scenarios.py and docs/benchmarks.md)",
    )
    p.add_argument(
        "--policy", action="append", choices=POLICIES, help="only these policies (repeatable)"
    )
    add_time_scale(p, default=5.0)
    p.add_argument(
        "--time-limit",
        type=positive_float,
        metavar="S",
        help="simulated seconds after the last task's arrival before a run stops "
        "(default: each scenario's, 120 s or more)",
    )
    p.add_argument(
        "--perfect",
        action="store_true",
        help="no disturbances on anybody's robots (fleet and navground alike)",
    )
    p.add_argument(
        "--disturbance-seeds",
        type=positive_int,
        default=1,
        metavar="N",
        help="run every scenario with N sets of disturbances (seeds), every policy on each "
        "(default 1; the issue's targets use 3)",
    )
    p.add_argument(
        "--repeats",
        type=positive_int,
        default=1,
        metavar="N",
        help="run every (scenario, seed, policy) N times: the spread of one tree under the "
        "same disturbances (a fleet run varies with the service's timing; navground's peers "
        "repeat exactly) (default 1)",
    )
    p.add_argument("--plots", type=Path, metavar="DIR", help="one PNG per (scenario, policy)")
    p.add_argument(
        "--markdown",
        action="store_true",
        help="end with the tables of docs/benchmarks.md (policies side by side, auto's verdict)",
    )
    p.add_argument(
        "--from-json",
        type=Path,
        metavar="FILE",
        help="run nothing: print the tables of a previous --json output",
    )
    p.add_argument(
        "--traces",
        type=Path,
        metavar="DIR",
        help="keep the fleet runs' sim traces (fleet/io/trace.py format), task stores and "
        "plans logs there (a folder per run: its SQLite task history and plans.jsonl, one "
        "JSON line per plan)",
    )
    p.set_defaults(func=run)


def select(args: argparse.Namespace) -> list[Scenario]:
    """The scenarios the flags ask for."""
    if args.scenario_file:
        scenarios = [s for f in args.scenario_file for s in load_scenarios(f)]
    else:
        scenarios = quick_suite() if args.quick else full_suite()
    if args.scenario:
        scenarios = [
            s for s in scenarios if any(fnmatch.fnmatchcase(s.name, p) for p in args.scenario)
        ]
        if not scenarios:
            raise ValueError(f"no scenario matches {args.scenario}")
    return scenarios


HEADER = (
    f"{'run':>9} {'scenario':<22} {'N':>3} {'policy':<11} {'success':>7} {'coll':>4} "
    f"{'min sep':>7} {'makespan':>8} {'path':>5} {'dead':>4} {'obst':>4} "
    f"{'plan p50/p99 ms':>15} {'stop/cusp':>9} {'wait s':>6} {'wall s':>6}"
)


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def format_row(done: int, total: int, row: FleetBenchRow) -> str:
    plan = (
        "-" if row.plan_p50_ms is None else f"{row.plan_p50_ms:.0f}/{_fmt(row.plan_p99_ms, '.0f')}"
    )
    smooth = (
        "-"
        if row.stops_per_trip is None or row.cusps_per_trip is None
        else f"{row.stops_per_trip:.1f}/{row.cusps_per_trip:.1f}"
    )
    return (
        f"{f'{done}/{total}':>9} {row.scenario:<22} {row.robots:>3} {row.policy:<11} "
        f"{row.success_rate:>7.0%} {row.collisions:>4} {_fmt(row.min_separation_m, '.3f'):>7} "
        f"{row.makespan_s:>8.1f} {_fmt(row.path_ratio, '.2f'):>5} {row.deadlocks:>4} "
        f"{row.obstacle_hits:>4} {plan:>15} {smooth:>9} {_fmt(row.plan_wait_s, '.1f'):>6} "
        f"{row.wall_s:>6.0f}"
        + ("" if row.zone_solo_s is None else f"  (zones one at a time: {row.zone_solo_s:.0f} s)")
        + ("" if row.law_solo_s is None else f"  (the law alone: {row.law_solo_s:.0f} s)")
    )


def print_summary(summary: list[SummaryRow], out: TextIO) -> None:
    """Families with several runs (seeds): mean and worst."""
    many = [s for s in summary if s.runs > 1]
    if not many:
        return
    print(
        f"\n{'family':<18} {'N':>3} {'policy':<11} {'runs':>4} {'success mean/worst':>18} "
        f"{'coll mean/worst':>15} {'min sep worst':>13} {'makespan mean/worst':>19} "
        f"{'path mean/worst':>15} {'dead mean/worst':>15}",
        file=out,
    )
    for s in many:
        print(
            f"{s.family:<18} {s.robots:>3} {s.policy:<11} {s.runs:>4} "
            f"{f'{s.success_mean:.0%}/{s.success_worst:.0%}':>18} "
            f"{f'{s.collisions_mean:.1f}/{s.collisions_worst}':>15} "
            f"{_fmt(s.min_separation_worst_m, '.3f'):>13} "
            f"{f'{s.makespan_mean_s:.1f}/{s.makespan_worst_s:.1f}':>19} "
            f"{_fmt(s.path_ratio_mean, '.2f') + '/' + _fmt(s.path_ratio_worst, '.2f'):>15} "
            f"{f'{s.deadlocks_mean:.1f}/{s.deadlocks_worst}':>15}",
            file=out,
        )


def print_markdown(rows: list[FleetBenchRow], out: TextIO) -> None:
    tables = (
        policy_table(rows),
        auto_table(rows),
        smoothness_table(rows),
        planning_wait_table(rows),
        law_alone_table(rows),
    )
    print("\n" + "\n\n".join(t for t in tables if t), file=out)


def run(args: argparse.Namespace) -> int:
    if args.from_json is not None:
        try:
            data = json.loads(args.from_json.read_text())
            rows = [FleetBenchRow.model_validate(r) for r in data["rows"]]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{args.from_json}: not a bench fleet --json output ({exc})") from None
        print_markdown(rows, sys.stdout)
        return 0
    scenarios = select(args)
    policies = tuple(args.policy) if args.policy else POLICIES
    options = BenchOptions(
        time_scale=args.time_scale,
        disturbances=() if args.perfect else DISTURBED_FLAGS,
        time_limit_s=args.time_limit,
        plots=args.plots,
        traces=args.traces,
        settings=load_settings(),
        robots=SimRobots() if args.perfect else SimRobots.realistic(),
        disturbance_seeds=args.disturbance_seeds,
        repeats=args.repeats,
    )
    progress_out = sys.stderr if args.json else sys.stdout
    print(
        f"bench fleet: {len(scenarios)} scenarios x {len(policies)} policies, "
        f"robots {'perfect' if args.perfect else 'disturbed'}, time scale {args.time_scale:g}",
        file=progress_out,
    )
    print(HEADER, file=progress_out, flush=True)
    began = time.monotonic()

    def progress(done: int, total: int, row: FleetBenchRow) -> None:
        print(format_row(done, total, row), file=progress_out, flush=True)

    def starting(scenario: Scenario, policy: str) -> None:
        if sys.stderr.isatty():  # a live "now running" line, overwritten by the result
            print(f"{'...':>9} {scenario.name:<22} {policy}", end="\r", file=sys.stderr)

    rows = run_fleet_bench(scenarios, policies, options, progress, starting)
    summary = summarise(rows)
    wall = time.monotonic() - began
    if args.json:
        json.dump(
            {
                "rows": [r.model_dump() for r in rows],
                "summary": [s.model_dump() for s in summary],
                "disturbed": not args.perfect,
                "time_scale": args.time_scale,
                "wall_s": round(wall, 1),
            },
            sys.stdout,
        )
        print()
    else:
        print_summary(summary, sys.stdout)
        if args.markdown:
            print_markdown(rows, sys.stdout)
        print(f"\nwall time {wall:.0f} s", flush=True)
    return 0
