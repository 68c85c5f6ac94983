"""``parkfleet sim``: N simulated robots on one Zenoh session, until SIGINT/SIGTERM."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from fleet.settings import load_settings
from fleet.transport import open_session
from robot_agent.cli import stop_on_signals
from sim_agent.fleet import SimFleet, spawn_layout


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "sim",
        help="run N simulated robots (kinematic unicycles) as fleet agents",
        description="Runs N simulated robots sharing one Zenoh client session; each is a full "
        "robot agent (state, liveliness, assignments, avoidance). Stops on SIGINT/SIGTERM.",
    )
    p.add_argument("--robots", type=int, default=1, help="number of robots (default 1)")
    p.add_argument("--connect", action="append", metavar="ENDPOINT", help="router endpoint")
    p.add_argument("--config", type=Path, help="TOML settings file")
    p.add_argument("--time-scale", type=float, default=1.0, help="sim seconds per real second")
    p.add_argument("--spawn", default="grid", help="random | grid | FILE.json (default grid)")
    p.add_argument("--seed", type=int, help="random seed (spawn, noise)")
    p.add_argument("--id-prefix", default="robot-", help="robot ids are PREFIX1..PREFIXN")
    p.add_argument("--noise", type=float, default=0.0, help="pose noise std [m] (theta: /5 rad)")
    p.add_argument("--rate", type=float, help="control rate [Hz] (default 50)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if not args.time_scale > 0:
        raise ValueError("--time-scale must be positive")
    settings = load_settings(args.config, connect=args.connect, control_rate_hz=args.rate)
    spawns = spawn_layout(
        args.spawn, args.robots, seed=args.seed, id_prefix=args.id_prefix, yard=settings.yard
    )
    noise = (args.noise, args.noise, args.noise / 5.0)
    with stop_on_signals() as stop, open_session(settings, "client") as session:
        fleet = SimFleet(
            session, settings, spawns, time_scale=args.time_scale, noise_std=noise, seed=args.seed
        )
        try:
            fleet.open()
            print(
                f"sim: {len(spawns)} robots ({spawns[0].robot_id} ...) at "
                f"{settings.control_rate_hz:g} Hz, time scale {args.time_scale:g}",
                flush=True,
            )
            fleet.run(stop)
        finally:
            fleet.close()
    return 0
