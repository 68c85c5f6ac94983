"""Command-line flags shared by several commands: each is declared once, here."""

from __future__ import annotations

import argparse
from pathlib import Path

from fleet.io.settings import DB_FILE


def add_config(p: argparse.ArgumentParser) -> None:
    """``--config FILE``: the TOML settings file (also ``PARKFLEET_CONFIG``)."""
    p.add_argument("--config", type=Path, help="TOML settings file (also PARKFLEET_CONFIG)")


def add_connect(p: argparse.ArgumentParser, help: str = "router endpoint") -> None:
    """``--connect ENDPOINT`` (repeatable): Zenoh endpoints to connect to."""
    p.add_argument("--connect", action="append", metavar="ENDPOINT", help=f"{help}, repeatable")


def add_fleet(p: argparse.ArgumentParser) -> None:
    """``--fleet NAME``: the fleet addressed, overriding the settings' ``fleet_name``."""
    p.add_argument(
        "--fleet",
        metavar="NAME",
        help="fleet name (default: fleet_name of the settings, PARKFLEET_FLEET_NAME, 'default')",
    )


def add_json(p: argparse.ArgumentParser) -> None:
    """``--json``: machine-readable output."""
    p.add_argument("--json", action="store_true", help="print the results as one JSON object")


def add_rate(p: argparse.ArgumentParser) -> None:
    """``--rate HZ``: the agents' control rate."""
    p.add_argument("--rate", type=float, help="control rate [Hz] (default 50)")


def positive_float(text: str) -> float:
    """argparse type: a strictly positive number."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text}")
    return value


def add_time_scale(p: argparse.ArgumentParser, default: float = 1.0) -> None:
    """``--time-scale S``: simulated seconds per wall-clock second (lockstep simulation)."""
    p.add_argument(
        "--time-scale",
        type=positive_float,
        default=default,
        help=f"simulated seconds per wall-clock second (default {default:g})",
    )


def add_spawn(p: argparse.ArgumentParser, default: str) -> None:
    """``--spawn`` and ``--seed``: where simulated robots start."""
    p.add_argument(
        "--spawn", default=default, help=f"random | grid | FILE.json (default {default})"
    )
    p.add_argument("--seed", type=int, help="random seed (spawn places, noise)")


def add_server(
    p: argparse.ArgumentParser, *, default_data: str, default_site: str = "none"
) -> None:
    """``--port``, ``--zenoh-listen``, ``--data-dir``, ``--store``, ``--site``, ``--config`` of
    the API server."""
    p.add_argument("--port", type=int, help="API port (default 8000; 0: any free port)")
    p.add_argument(
        "--zenoh-listen",
        action="append",
        metavar="ENDPOINT",
        help="Zenoh router endpoint, repeatable (default tcp/127.0.0.1:7447)",
    )
    p.add_argument("--data-dir", type=Path, help=f"where {DB_FILE} lives (default {default_data})")
    p.add_argument(
        "--store",
        metavar="URL_OR_FILE",
        help=f"task store: a SQLite file (default <data-dir>/{DB_FILE}) or a "
        "postgresql://user@host/db URL: leader or standby on a shared database",
    )
    add_site(p, default_site)
    add_config(p)


def add_site(p: argparse.ArgumentParser, default: str = "none") -> None:
    """``--site FILE``: the site map (TOML or JSON: yard, obstacles, keep-out zones, bays)."""
    p.add_argument(
        "--site",
        metavar="FILE",
        help=(
            f"site map, TOML or JSON (docs/operating.md 'Site map'; 'none': no site; "
            f"default {default})"
        ),
    )
