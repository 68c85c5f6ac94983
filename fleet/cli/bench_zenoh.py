"""``parkfleet bench zenoh``: robots' states at the agents' rate into the fleet service."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from fleet.cli.options import add_json, positive_float


def register(commands: Any, bench: Any) -> None:
    from fleet.bench import zenoh as bench_zenoh

    p = bench.add_parser(
        "zenoh",
        help="N simulated robots' state streams through a router into the service and robots",
        description=bench_zenoh.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_json(p)
    p.add_argument(
        "--robots", type=int, action="append", help="robot count (repeatable; default 10 100 1000)"
    )
    p.add_argument(
        "--rate", type=positive_float, default=50.0, help="robots' control rate [Hz] (default 50)"
    )
    p.add_argument("--window", type=positive_float, default=10.0, help="measuring window per N [s]")
    p.add_argument("--warmup", type=float, default=3.0, help="warm-up per N [s]")
    p.add_argument(
        "--source",
        choices=("agents", "stream"),
        default="agents",
        help="robots: full simulated agents (parkfleet sim, default) or a light stream of "
        "their state messages (no control loop: loads the service beyond what a simulated "
        "fleet reaches on a small machine)",
    )
    p.add_argument(
        "--area",
        type=positive_float,
        default=10.0,
        help="robots stand at seeded random spots, one per AREA m² (default 10)",
    )
    p.add_argument(
        "--profile", type=Path, help="py-spy recording of the service for the largest N (.svg)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.zenoh import DEFAULT_SIZES
    from fleet.bench.zenoh import run as run_zenoh_bench

    sizes = args.robots or list(DEFAULT_SIZES)
    return run_zenoh_bench(
        sizes,
        args.warmup,
        args.window,
        args.rate,
        as_json=args.json,
        profile=args.profile,
        source=args.source,
        area=args.area,
    )
