"""``parkfleet bench sim``: robot-steps per second of the batch simulator vs a plain loop."""

from __future__ import annotations

import argparse
import json
from typing import Any

from fleet.cli.options import add_json

#: The issue's target at N = 10 000 on one core [robot-steps/s] and its ratio to the loop.
TARGET_STEPS_PER_S = 20e6
TARGET_RATIO = 50.0


def register(commands: Any, bench: Any) -> None:
    p = bench.add_parser(
        "sim",
        help="robot-steps/s of the batch simulator for 1 to 100 000 robots, vs a Python loop",
        description="Times fleet.core.simulate.simulate (no obstacles, no wheel limit, random "
        "postures with a fixed seed) for N = 1, 100, 10 000 and 100 000 robots and, in the "
        "same run, the plain per-robot Python loop of fleet.core.reference on 50 robots; prints "
        "robot-steps per CPU second (and per wall-clock second) and their ratio. Takes "
        "about half a minute on an idle machine.",
    )
    add_json(p)
    p.add_argument("--quick", action="store_true", help=argparse.SUPPRESS)  # tests only
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.sim import quick_bench, run_sim_bench

    report = quick_bench() if args.quick else run_sim_bench()
    if args.json:
        rows = [
            {"robots": r.robots, "steps_per_s": r.steps_per_s, "ratio_vs_loop": r.ratio_vs_loop}
            for r in report.rows
        ]
        print(json.dumps({"rows": rows}))
        return 0
    print(f"{'robots':>8} {'steps':>6} {'robot-steps/s':>15} {'vs loop':>9} {'(wall clock)':>15}")
    for r in report.rows:
        print(
            f"{r.robots:>8} {r.steps:>6} {r.steps_per_s:>15,.0f} {r.ratio_vs_loop:>8.1f}x "
            f"{r.wall_steps_per_s:>15,.0f}"
        )
    print(
        f"plain Python loop (fleet.core.reference, {report.loop_robots} robots x "
        f"{report.loop_steps} steps): {report.loop_steps_per_s:,.0f} robot-steps/s "
        f"({report.loop_wall_steps_per_s:,.0f} wall clock)"
    )
    print(f"rates per CPU second of this process (one core), best of {report.repeats} runs")
    print(
        f"target at N = 10 000: >= {TARGET_STEPS_PER_S:,.0f} robot-steps/s, "
        f">= {TARGET_RATIO:.0f}x the loop"
    )
    return 0
