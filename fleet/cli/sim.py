"""``parkfleet sim``: N simulated robots on one Zenoh session, until SIGINT/SIGTERM."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any, TypeVar

from fleet.cli.options import add_config, add_connect, add_rate, add_spawn, add_time_scale
from fleet.cli.signals import stop_on_signals
from fleet.io.settings import load_settings
from fleet.io.transport import open_session
from sim_agent.disturbances import REALISTIC, REALISTIC_LINK, Disturbances, LinkDisturbances
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
    add_rate(p)
    d = p.add_argument_group(
        "disturbances (seeded by --seed)",
        "A real robot's imperfections on every simulated robot; all off by default.",
    )
    d.add_argument(
        "--disturbed",
        action="store_true",
        help="the fleet benchmark's set: --pose-noise 0.01 --heading-noise 0.5 "
        "--actuation-noise 0.05 --wheel-bias 0.02 --latency 50,150 --link-delay 20,200 "
        "--link-loss 0.05 (flags given win)",
    )
    d.add_argument("--pose-noise", type=float, metavar="M", help="std of reported x, y [m]")
    d.add_argument("--heading-noise", type=float, metavar="DEG", help="std of reported theta [deg]")
    d.add_argument(
        "--noise", type=float, metavar="M", help="shorthand: --pose-noise M, theta std M/5 rad"
    )
    d.add_argument(
        "--actuation-noise", type=float, metavar="FRAC", help="relative std per wheel command"
    )
    d.add_argument(
        "--wheel-bias", type=float, metavar="FRAC", help="relative std of a per-robot wheel gain"
    )
    d.add_argument(
        "--latency",
        type=_latency_ms,
        metavar="MIN[,MAX]",
        help="command latency [ms], uniform in [MIN, MAX]",
    )
    d.add_argument(
        "--link-delay",
        type=_latency_ms,
        metavar="MIN[,MAX]",
        help="delay of each peer state between robots [ms], uniform in [MIN, MAX]",
    )
    d.add_argument(
        "--link-loss",
        type=_fraction,
        metavar="FRAC",
        help="share of peer states lost between robots",
    )
    p.add_argument(
        "--trace",
        type=Path,
        metavar="FILE",
        help="write every robot's true pose and mode at every tick to FILE (fleet.io.trace)",
    )
    p.set_defaults(func=run)


def _latency_ms(text: str) -> tuple[float, float]:
    """``MIN[,MAX]`` milliseconds -> (min, max) seconds."""
    try:
        parts = [float(v) for v in text.split(",")]
    except ValueError:
        parts = []
    if len(parts) not in (1, 2) or not all(math.isfinite(v) and v >= 0 for v in parts):
        raise argparse.ArgumentTypeError(f"expected MIN[,MAX] in ms (>= 0), got {text!r}")
    low, high = parts[0], parts[-1]
    if high < low:
        raise argparse.ArgumentTypeError(f"MAX must be >= MIN, got {text!r}")
    return (low / 1e3, high / 1e3)


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 1), got {text!r}")
    return value


def link_from(args: argparse.Namespace) -> LinkDisturbances:
    """The :class:`LinkDisturbances` the flags ask for (``--disturbed`` as the base)."""
    base = REALISTIC_LINK if args.disturbed else LinkDisturbances()
    return LinkDisturbances(
        delay_s=_given(args.link_delay, base.delay_s), loss=_given(args.link_loss, base.loss)
    )


def disturbances_from(args: argparse.Namespace) -> Disturbances:
    """The :class:`Disturbances` the flags ask for (``--disturbed`` as the base)."""
    base = REALISTIC if args.disturbed else Disturbances()
    pose, heading = base.pose_noise_m, base.heading_noise_rad
    if args.noise is not None:
        pose, heading = args.noise, args.noise / 5.0
    if args.pose_noise is not None:
        pose = args.pose_noise
    if args.heading_noise is not None:
        heading = math.radians(args.heading_noise)
    return Disturbances(
        pose_noise_m=pose,
        heading_noise_rad=heading,
        actuation_noise=_given(args.actuation_noise, base.actuation_noise),
        actuation_bias=_given(args.wheel_bias, base.actuation_bias),
        latency_s=_given(args.latency, base.latency_s),
    )


T = TypeVar("T")


def _given(value: T | None, default: T) -> T:
    return default if value is None else value


def run(args: argparse.Namespace) -> int:
    settings = load_settings(args.config, connect=args.connect, control_rate_hz=args.rate)
    spawns = spawn_layout(
        args.spawn, args.robots, seed=args.seed, id_prefix=args.id_prefix, yard=settings.yard
    )
    disturbances = disturbances_from(args)
    with stop_on_signals() as stop, open_session(settings, "client") as session:
        fleet = SimFleet(
            session,
            settings,
            spawns,
            time_scale=args.time_scale,
            seed=args.seed,
            disturbances=disturbances,
            link=link_from(args),
            trace=args.trace,
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
