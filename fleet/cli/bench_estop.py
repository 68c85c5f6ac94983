"""``parkfleet bench estop``: e-stop latency from the request to zero wheel speed."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_json


def register(commands: Any, bench: Any) -> None:
    from fleet.bench import estop

    p = bench.add_parser(
        "estop",
        help="e-stop latency: request -> the wheels stop, N simulated robots over Zenoh",
        description=estop.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_json(p)
    p.add_argument(
        "--robots", type=int, action="append", help="robot count (repeatable; default 10 100)"
    )
    p.add_argument("--trials", type=int, default=20, help="e-stops per robot count")
    p.add_argument(
        "--cli-trials",
        type=int,
        default=3,
        help="then this many e-stops through the real `parkfleet estop` command (default 3)",
    )
    p.add_argument(
        "--perfect",
        action="store_true",
        help="robots without disturbances (default: the fleet bench's, 50-150 ms to the wheels)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench import estop

    return estop.run(
        args.robots or list(estop.DEFAULT_SIZES),
        args.trials,
        as_json=args.json,
        cli_trials=max(args.cli_trials, 0),
        disturbed=not args.perfect,
    )
