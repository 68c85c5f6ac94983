"""``parkfleet bench failover``: kill the leading fleet service N times; time the take-over."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_json


def register(commands: Any, bench: Any) -> None:
    from fleet.bench import failover

    p = bench.add_parser(
        "failover",
        help="two services on one PostgreSQL: SIGKILL the leader N times, time the take-over",
        description=failover.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_json(p)
    p.add_argument(
        "--robots",
        type=int,
        default=failover.DEFAULT_ROBOTS,
        help=f"simulated robots (default {failover.DEFAULT_ROBOTS}; the issue's figure is 50)",
    )
    p.add_argument("--kills", type=int, default=failover.DEFAULT_KILLS, help="leader kills")
    p.add_argument(
        "--mode",
        choices=["kill", "stop"],
        default="kill",
        help="kill: SIGKILL the leader; stop: SIGSTOP it past its lease, then SIGCONT",
    )
    p.add_argument("--interval", type=float, default=1.0, help="seconds between tasks")
    p.add_argument("--drain", type=float, default=30.0, help="seconds to let tasks finish")
    p.add_argument("--store", help="postgresql:// URL of an empty database (default: a "
                   "throwaway cluster)")  # fmt: skip
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench import failover

    return failover.run(
        args.robots,
        args.kills,
        mode=args.mode,
        interval_s=args.interval,
        drain_s=args.drain,
        store=args.store,
        as_json=args.json,
    )
