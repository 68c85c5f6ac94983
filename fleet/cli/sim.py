"""``parkfleet sim``: N simulated robots on one Zenoh session, until SIGINT/SIGTERM."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_config, add_connect, add_rate, add_spawn, add_time_scale
from fleet.cli.signals import stop_on_signals
from fleet.io.settings import load_settings
from fleet.io.transport import open_session
from sim_agent.fleet import SimFleet, spawn_layout


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "sim",
        help="run N simulated robots (kinematic unicycles) as fleet agents",
        description="Runs N simulated robots sharing one Zenoh client session; each is a full "
        "robot agent (state, liveliness, assignments, avoidance). Stops on SIGINT/SIGTERM.",
    )
    p.add_argument("--robots", type=int, default=1, help="number of robots (default 1)")
    add_connect(p)
    add_config(p)
    add_time_scale(p)
    add_spawn(p, default="grid")
    p.add_argument("--id-prefix", default="robot-", help="robot ids are PREFIX1..PREFIXN")
    p.add_argument("--noise", type=float, default=0.0, help="pose noise std [m] (theta: /5 rad)")
    add_rate(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
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
