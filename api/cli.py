"""``parkfleet serve``, ``parkfleet demo`` and ``parkfleet bench api``."""

from __future__ import annotations

import argparse
import asyncio
from pathlib import Path
from typing import Any

from fleet.settings import Settings, load_settings


def _common(p: argparse.ArgumentParser, *, default_data: str) -> None:
    p.add_argument("--port", type=int, help="API port (default 8000; 0: any free port)")
    p.add_argument(
        "--zenoh-listen",
        action="append",
        metavar="ENDPOINT",
        help="Zenoh router endpoint, repeatable (default tcp/127.0.0.1:7447)",
    )
    p.add_argument(
        "--data-dir", type=Path, help=f"where parkfleet.db lives (default {default_data})"
    )
    p.add_argument("--config", type=Path, help="TOML settings file (also PARKFLEET_CONFIG)")


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "serve",
        help="run the fleet service, the REST API and the Zenoh router in one process",
        description="Serves the REST API (docs at /docs) with the fleet service and a Zenoh "
        "router. Binds 127.0.0.1 unless told otherwise; a non-loopback address needs "
        "PARKFLEET_API_TOKEN. SIGINT/SIGTERM stop it gracefully.",
    )
    p.add_argument("--host", help="API address (default 127.0.0.1)")
    _common(p, default_data="./var")
    p.set_defaults(func=run_serve)

    d = commands.add_parser(
        "demo",
        help="serve plus N simulated robots on this machine; prints a curl example",
        description="Runs `parkfleet serve` and a `parkfleet sim` subprocess with N robots "
        "connected to its Zenoh router, then prints the URL and a curl example.",
    )
    d.add_argument("--robots", type=int, default=4, help="number of simulated robots (default 4)")
    d.add_argument(
        "--time-scale", type=float, default=1.0, help="simulated seconds per wall second"
    )
    d.add_argument("--spawn", default="random", help="random | grid | FILE (default random)")
    d.add_argument("--seed", type=int, help="seed of the random spawn places")
    _common(d, default_data="./var/demo")
    d.set_defaults(func=run_demo)

    b = bench.add_parser(
        "api",
        help="POST /tasks throughput and p50/p99 latency against a live server",
        description="Starts `parkfleet serve` in a subprocess (temporary store, no robots), "
        "then posts tasks from concurrent HTTP clients.",
    )
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--requests", type=int, default=3000, help="timed POSTs (default 3000)")
    b.add_argument("--concurrency", type=int, default=16, help="concurrent clients (default 16)")
    b.set_defaults(func=run_bench)


def _settings(args: argparse.Namespace, **extra: Any) -> Settings:
    overrides: dict[str, Any] = {
        "api_port": args.port,
        "data_dir": args.data_dir,
        "listen": args.zenoh_listen,
        **extra,
    }
    return load_settings(args.config, **overrides)


def run_serve(args: argparse.Namespace) -> int:
    from api import server

    settings = _settings(args, api_host=args.host)

    async def ready(running: server.Running) -> None:
        # One parseable line: tests and scripts wait for it.
        print(
            f"parkfleet serve: API on {running.url} (docs {running.url}/docs); "
            f"Zenoh router on {' '.join(running.zenoh)}",
            flush=True,
        )

    return asyncio.run(server.serve(settings, on_ready=ready, access_log=args.verbose > 0))


def run_demo(args: argparse.Namespace) -> int:
    from api.demo import DemoOptions, run_demo

    if args.robots < 1:
        raise ValueError("--robots must be at least 1")
    settings = _settings(args)
    if args.data_dir is None and "data_dir" not in settings.model_fields_set:
        settings = settings.model_copy(update={"data_dir": Path("var/demo")})
    options = DemoOptions(
        robots=args.robots, time_scale=args.time_scale, spawn=args.spawn, seed=args.seed
    )
    return asyncio.run(run_demo(settings, options))


def run_bench(args: argparse.Namespace) -> int:
    from api.bench import run

    return run(requests=args.requests, concurrency=args.concurrency, as_json=args.json)
