"""``parkfleet bench zenoh``: state delivery of N simulated robots through a router."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_json


def register(commands: Any, bench: Any) -> None:
    from fleet.bench import zenoh as bench_zenoh

    bench_doc = bench_zenoh.__doc__
    p = bench.add_parser(
        "zenoh",
        help="N simulated robots publish state at 10 Hz through a router to one subscriber",
        description=bench_doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_json(p)
    p.add_argument(
        "--robots", type=int, action="append", help="robot count (repeatable; default 10 100 1000)"
    )
    p.add_argument("--window", type=float, default=5.0, help="measuring window per N [s]")
    p.add_argument("--warmup", type=float, default=2.0, help="warm-up per N [s]")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.zenoh import DEFAULT_SIZES
    from fleet.bench.zenoh import run as run_zenoh_bench

    sizes = args.robots or list(DEFAULT_SIZES)
    return run_zenoh_bench(sizes, args.warmup, args.window, as_json=args.json)
