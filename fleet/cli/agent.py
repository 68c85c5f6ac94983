"""``parkfleet agent``: run one robot agent on a robot computer.

The robot's hardware comes in through ``--drive module:factory``: ``factory(settings)``
must return a :class:`robot_agent.drive.Drive`. Without ``--drive`` the command refuses
to start (a real robot must never silently run a simulation); ``--drive sim`` runs the
simulated unicycle from ``--start X,Y,THETA`` instead, for trying things out.
"""

from __future__ import annotations

import argparse
import importlib
import logging
from collections.abc import Callable
from typing import Any

from fleet.cli.options import add_config, add_connect, add_rate
from fleet.cli.signals import stop_on_signals
from fleet.io.settings import RobotSettings, load_robot_settings
from fleet.io.transport import open_session
from robot_agent.agent import RobotAgent
from robot_agent.drive import Drive

_log = logging.getLogger(__name__)

NO_DRIVE_HELP = """no --drive given: parkfleet agent needs your robot's Drive.
Write a module with a factory `make_drive(settings) -> Drive` whose object has
  read_pose() -> (fleet.core.wire.Pose, stamp)  # world frame; stamp: time.monotonic() measured
  command_wheels(right_rad_s, left_rad_s)   # wheel angular speeds, held until the next call
  stop()                                    # both wheels to zero
(see robot_agent/drive.py), then run: parkfleet agent --id ID --drive mypkg.mydrive:make_drive
To try the agent without hardware use --drive sim [--start X,Y,THETA]."""


def parse_pose(text: str) -> tuple[float, float, float]:
    """``"x,y,theta"`` (m, m, rad) -> tuple; theta may be omitted."""
    parts = [float(p) for p in text.split(",")]
    if len(parts) == 2:
        parts.append(0.0)
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"expected X,Y[,THETA], got {text!r}")
    return (parts[0], parts[1], parts[2])


#: Drives known by a short name (``--drive NAME``); any other drive is ``module:factory``.
DRIVES = {
    "sim": "sim_agent.drive:make_drive",
    "ros2": "robot_agent.drives.ros2:make_drive",
}


def load_drive(spec: str | None, settings: RobotSettings) -> Drive:
    """Build the Drive named by ``--drive`` (a name in :data:`DRIVES` or ``module:factory``)."""
    if not spec:
        raise ValueError(NO_DRIVE_HELP)
    if spec == "sim":
        _log.warning("running a SIMULATED drive (--drive sim): no hardware is moved")
    target = DRIVES.get(spec, spec)
    module_name, sep, attr = target.partition(":")
    if not sep or not module_name or not attr:
        names = ", ".join(sorted(DRIVES))
        raise ValueError(f"--drive must be module:factory or one of {names}, got {spec!r}")
    factory: Callable[[RobotSettings], Any] = getattr(importlib.import_module(module_name), attr)
    drive = factory(settings)
    missing = [m for m in ("read_pose", "command_wheels", "stop") if not hasattr(drive, m)]
    if missing:
        raise ValueError(f"{spec} returned {type(drive).__name__}, missing {', '.join(missing)}")
    return drive  # type: ignore[no-any-return]


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "agent",
        help="run one robot agent (control loop + Zenoh) over a Drive",
        description="Runs the control loop of one robot: publishes its state and liveliness, "
        "obeys assignments, avoids peers and obstacles. Stops on SIGINT/SIGTERM.",
    )
    p.add_argument("--id", required=True, help="robot id (A-Z a-z 0-9 _ . -)")
    add_connect(p)
    add_config(p)
    p.add_argument("--drive", help="module:factory returning a Drive, or 'sim' (settings: drive)")
    p.add_argument("--start", type=parse_pose, help="start X,Y,THETA of --drive sim [m, m, rad]")
    add_rate(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    settings = load_robot_settings(  # a robot's settings: no host (api_*, service) fields
        args.config,
        connect=args.connect,
        robot_id=args.id,
        control_rate_hz=args.rate,
        drive=args.drive,
        sim_start=args.start,
    )
    drive = load_drive(settings.drive, settings)
    assert settings.robot_id is not None
    try:
        with stop_on_signals() as stop, open_session(settings, "client") as session:
            agent = RobotAgent(settings.robot_id, drive, session, settings)
            try:
                agent.open()
                print(
                    f"agent {settings.robot_id} running at {settings.control_rate_hz:g} Hz",
                    flush=True,
                )
                agent.run(stop)
            finally:
                agent.close()
    finally:
        close_drive(drive)
    return 0


def close_drive(drive: Drive) -> None:
    """Release a drive that holds resources (an optional ``close()``, e.g. its own session)."""
    close = getattr(drive, "close", None)
    if callable(close):
        close()
