"""``parkfleet bench soak --minutes M``: the server under a long random load stays flat."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_json, positive_float


def register(commands: Any, bench: Any) -> None:
    from fleet.bench import soak as bench_soak

    p = bench.add_parser(
        "soak",
        help="serve + simulated robots + random tasks, cancels, event clients and robot "
        "kills for M minutes: RSS/fds slopes, and no accepted task lost",
        description=bench_soak.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_json(p)
    p.add_argument("--minutes", type=positive_float, required=True, help="how long [min]")
    p.add_argument("--robots", type=int, default=50, help="simulated robots (default 50)")
    p.add_argument("--groups", type=int, default=5, help="sim processes they run in (default 5)")
    p.add_argument(
        "--time-scale", type=positive_float, default=4.0, help="robot time per second (default 4)"
    )
    p.add_argument(
        "--rate", type=positive_float, default=10.0, help="robots' control rate [Hz] (default 10)"
    )
    p.add_argument(
        "--tasks-per-s", type=positive_float, default=2.0, help="task stream rate (default 2/s)"
    )
    p.add_argument("--event-clients", type=int, default=4, help="event-stream clients (default 4)")
    p.add_argument(
        "--sample-s", type=positive_float, default=60.0, help="sampling interval [s] (default 60)"
    )
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fleet.bench.soak import run as run_soak

    if args.robots < args.groups or args.groups < 1:
        raise ValueError("--robots must be at least --groups, and --groups at least 1")
    return run_soak(
        args.minutes,
        as_json=args.json,
        robots=args.robots,
        groups=args.groups,
        time_scale=args.time_scale,
        rate=args.rate,
        tasks_per_s=args.tasks_per_s,
        event_clients=args.event_clients,
        sample_s=args.sample_s,
        seed=args.seed,
    )
