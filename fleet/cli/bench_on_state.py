"""``parkfleet bench on-state``: robot states per CPU second through the service's hot path."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from typing import Any

from fleet.cli.options import add_json

#: 1 000 robots at 50 Hz, the issue's load, as states per second of one core.
TARGET_STATES_PER_S = 50_000


def register(commands: Any, bench: Any) -> None:
    p = bench.add_parser(
        "on-state",
        help="states/s of FleetService.on_state on one core (1 000 robots, idle and driving)",
        description="Feeds pre-built robot states of N robots (50 Hz rounds on a fake clock) "
        "into FleetService.on_state with an in-memory bus and store and one listener; "
        "prints states per CPU second of the calling thread and microseconds per state, for "
        "idle robots (pose-only updates) and robots driving their tasks (task check and path "
        "recording), best of 3 runs. Takes a few seconds.",
    )
    add_json(p)
    p.add_argument("--robots", type=int, default=1000, help="robots (default 1000)")
    p.add_argument("--rounds", type=int, default=50, help="states per robot (default 50)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.on_state import run_on_state_bench

    if args.robots < 1 or args.rounds < 1:
        raise ValueError("--robots and --rounds must be at least 1")
    rows = run_on_state_bench(args.robots, args.rounds)
    if args.json:
        print(json.dumps({"rows": [asdict(r) for r in rows]}))
        return 0
    print(f"{'workload':>9} {'robots':>7} {'states':>8} {'states/CPU-s':>13} {'us/state':>9}")
    for r in rows:
        print(
            f"{r.workload:>9} {r.robots:>7} {r.states:>8} {r.states_per_cpu_s:>13,.0f} "
            f"{r.us_per_state:>9.2f}"
        )
    print(
        f"one core; the load of 1 000 robots at 50 Hz is {TARGET_STATES_PER_S:,} states/s "
        "(plus decoding, which the bus does)"
    )
    return 0
