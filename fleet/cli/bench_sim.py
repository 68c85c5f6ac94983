"""``parkfleet bench sim``: robot-steps per second of the batch simulator vs a plain loop."""

from __future__ import annotations

import argparse
import json
from typing import Any

from fleet.cli.options import add_json

#: The issue's target at N = 10 000 on this 2-core machine [robot-steps/s, wall clock].
TARGET_STEPS_PER_S = 50e6
#: The safety filter's share of the step's throughput it must keep (peers+filter / peers).
FILTER_SHARE_TARGET = 0.5


def register(commands: Any, bench: Any) -> None:
    p = bench.add_parser(
        "sim",
        help="robot-steps/s of the batch simulator (1 to 100 000 robots, and 50 interacting "
        "robots) vs a plain Python loop",
        description="Times fleet.core.simulate.simulate, the compiled control step, on random "
        "postures with a fixed seed: N = 1, 100, 10 000 and 100 000 independent robots (no "
        "obstacles, no wheel limit) and 50 wheel-limited robots that all act on each other "
        "at every step (Eq. 27), without and with the safety filter (rows peers and "
        "peers+filter; the target: the filter at >= 0.5x the step without it). In the same "
        "run it times a fair "
        "plain-Python loop doing the same job (cos/sin once per robot-step, inlined) on 50 "
        "robots of each scene. Prints robot-steps per wall-clock second (large batches use "
        "both cores) and per CPU second, and the ratio to the loop. About half a minute.",
    )
    add_json(p)
    p.add_argument("--quick", action="store_true", help=argparse.SUPPRESS)  # tests only
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.sim import quick_bench, run_sim_bench

    report = quick_bench() if args.quick else run_sim_bench()
    if args.json:
        rows = [
            {
                "scene": r.scene,
                "robots": r.robots,
                "steps_per_s": r.steps_per_s,
                "cpu_steps_per_s": r.cpu_steps_per_s,
                "ratio_vs_loop": r.ratio_vs_loop,
                "loop_steps_per_s": r.loop_steps_per_s,
                "cpu_ratio_vs_loop": r.cpu_ratio_vs_loop,
            }
            for r in report.rows
        ]
        print(json.dumps({"rows": rows}))
        return 0
    print(
        f"{'scene':<12} {'robots':>7} {'steps':>6} {'robot-steps/s':>15} {'vs loop':>9} "
        f"{'per CPU s':>13} {'vs loop':>9} {'loop/s':>11}"
    )
    for r in report.rows:
        print(
            f"{r.scene:<12} {r.robots:>7} {r.steps:>6} {r.steps_per_s:>15,.0f} "
            f"{r.ratio_vs_loop:>8.1f}x {r.cpu_steps_per_s:>13,.0f} {r.cpu_ratio_vs_loop:>8.1f}x "
            f"{r.loop_steps_per_s:>11,.0f}"
        )
    print(
        "robot-steps per wall-clock second (and per CPU second, all threads), best of "
        f"{report.repeats} runs; the loop: plain Python on 50 robots of the same scene"
    )
    print(f"target at N = 10 000: >= {TARGET_STEPS_PER_S:,.0f} robot-steps/s (wall clock)")
    by_scene = {r.scene: r for r in report.rows}
    if "peers" in by_scene and "peers+filter" in by_scene:
        share = by_scene["peers+filter"].steps_per_s / by_scene["peers"].steps_per_s
        print(f"peers+filter / peers: {share:.2f}x (target: >= {FILTER_SHARE_TARGET}x)")
    return 0
