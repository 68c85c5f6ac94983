"""``parkfleet router``: a standalone Zenoh router (a router-mode Python session)."""

from __future__ import annotations

import argparse
import signal
import threading
from pathlib import Path
from types import FrameType
from typing import Any

from fleet.settings import load_settings
from fleet.transport import listening_locators, open_session


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
    p.add_argument("--connect", action="append", metavar="ENDPOINT", help="other routers")
    p.add_argument("--config", type=Path, help="TOML settings file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    settings = load_settings(args.config, listen=args.listen, connect=args.connect)
    stop = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with open_session(settings, "router") as session:
            for locator in listening_locators(session):
                print(f"router listening on {locator}", flush=True)
            print(f"router zid {session.info.zid()}", flush=True)
            while not stop.wait(0.5):
                pass
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
    return 0
