"""``parkfleet serve``: the fleet service, the REST API and the Zenoh router in one process."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from fleet.cli.options import add_server
from fleet.io.settings import Settings, load_settings


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "serve",
        help="run the fleet service, the REST API and the Zenoh router in one process",
        description="Serves the REST API (docs at /docs) with the fleet service and a Zenoh "
        "router. Binds 127.0.0.1 unless told otherwise; a non-loopback address needs "
        "PARKFLEET_API_TOKEN. SIGINT/SIGTERM stop it gracefully.",
    )
    p.add_argument("--host", help="API address (default 127.0.0.1)")
    add_server(p, default_data="./var")
    p.set_defaults(func=run_serve)


def server_settings(args: argparse.Namespace, **extra: Any) -> Settings:
    """Settings of ``serve`` and ``demo`` from their flags (``options.add_server``)."""
    overrides: dict[str, Any] = {
        "api_port": args.port,
        "data_dir": args.data_dir,
        "store": getattr(args, "store", None),
        "listen": args.zenoh_listen,
        "site_file": None if args.site in (None, "none") else Path(args.site),
        **extra,
    }
    return load_settings(args.config, **overrides)


def run_serve(args: argparse.Namespace) -> int:
    from api import server

    settings = server_settings(args, api_host=args.host)

    async def ready(running: server.Running) -> None:
        # One parseable line: tests and scripts wait for it.
        print(
            f"parkfleet serve: API on {running.url} (docs {running.url}/docs); "
            f"Zenoh router on {' '.join(running.zenoh)}",
            flush=True,
        )

    return server.run_loop(server.serve(settings, on_ready=ready, access_log=args.verbose > 0))
