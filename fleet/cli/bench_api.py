"""``parkfleet bench api``: POST /tasks throughput and latency against a live server."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_json, positive_float


def register(commands: Any, bench: Any) -> None:
    b = bench.add_parser(
        "api",
        help="POST /tasks throughput and p50/p99 latency against a live server under load",
        description="Starts `parkfleet serve` (temporary store) and `parkfleet sim` robots "
        "streaming state to it, then posts tasks from concurrent HTTP clients.",
    )
    add_json(b)
    b.add_argument("--requests", type=int, default=3000, help="timed POSTs (default 3000)")
    b.add_argument("--concurrency", type=int, default=16, help="concurrent clients (default 16)")
    b.add_argument(
        "--robots", type=int, default=50, help="simulated robots streaming state (default 50)"
    )
    b.add_argument(
        "--rate", type=positive_float, default=50.0, help="their control rate [Hz] (default 50)"
    )
    b.add_argument(
        "--planner",
        choices=("thread", "process", "both"),
        default="process",
        help="where the server plans: in its own process (planner_process, the default, as "
        "serve's), on a thread, or both, one server after the other (default process)",
    )
    b.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.api import run as run_api_bench

    return run_api_bench(
        requests=args.requests,
        concurrency=args.concurrency,
        as_json=args.json,
        robots=args.robots,
        rate=args.rate,
        planners=("thread", "process") if args.planner == "both" else (args.planner,),
    )
