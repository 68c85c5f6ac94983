"""``parkfleet router``: a standalone Zenoh router (a router-mode Python session)."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_config, add_connect
from fleet.cli.signals import stop_on_signals
from fleet.io.settings import load_settings
from fleet.io.transport import listening_locators, open_session


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "router",
        help="run a standalone Zenoh router (until SIGINT/SIGTERM)",
        description="Runs a Zenoh router-mode session: agents and services connect to it; "
        "--connect meshes it with other routers. Prints the locators it listens on.",
    )
    p.add_argument(
        "--listen", action="append", metavar="ENDPOINT", help="default tcp/127.0.0.1:7447"
    )
    add_connect(p, help="other routers")
    add_config(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    settings = load_settings(args.config, listen=args.listen, connect=args.connect)
    with stop_on_signals() as stop, open_session(settings, "router") as session:
        for locator in listening_locators(session):
            print(f"router listening on {locator}", flush=True)
        print(f"router zid {session.info.zid()}", flush=True)
        stop.wait()
    return 0
