"""``parkfleet estop | pause | resume``: operator commands straight to the robots over Zenoh.

The command opens its own client session to the fleet's router and publishes a
``ControlCommand`` on the key every agent obeys (``fleet.core.wire``), so it works while the
fleet service is down. It re-sends until every robot concerned (``--robot ID``, or every
robot online) reports a state that obeys, or ``--wait`` passes, and prints who confirmed and
how fast. Exit code 0 when all confirmed, 1 otherwise.
"""

from __future__ import annotations

import argparse
from typing import Any

from fleet.cli.options import add_config, add_connect
from fleet.core.wire import ControlAction, Keys, validate_id
from fleet.io import operator
from fleet.io.settings import load_settings
from fleet.io.transport import open_session

HELP = {
    "estop": "emergency stop: wheels to zero at once, tasks held, latched until --release",
    "pause": "pause: robots stop and keep their tasks until resume",
    "resume": "resume paused robots (an e-stopped robot needs estop --release)",
}


def register(commands: Any, bench: Any) -> None:
    for name, text in HELP.items():
        p = commands.add_parser(
            name,
            help=text,
            description=f"{text[0].upper()}{text[1:]}. Publishes on the Zenoh key the robots "
            "obey directly (works without the fleet service) and waits until they confirm.",
        )
        p.add_argument("--robot", metavar="ID", help="one robot (default: the whole fleet)")
        if name == "estop":
            p.add_argument("--release", action="store_true", help="release the e-stop latch")
        p.add_argument("--reason", help="why (shown in the robots' state)")
        p.add_argument("--issuer", help="who sends it (default cli-<host name>)")
        p.add_argument(
            "--wait",
            type=float,
            default=3.0,
            metavar="S",
            help="seconds to wait for the robots to confirm (0: send once, don't wait)",
        )
        add_connect(p)
        add_config(p)
        p.set_defaults(func=run, action=name)


def run(args: argparse.Namespace) -> int:
    settings = load_settings(args.config, connect=args.connect)
    action = ControlAction(args.action)
    if action is ControlAction.ESTOP and args.release:
        action = ControlAction.RELEASE
    robot = None if args.robot is None else validate_id(args.robot)
    issuer = validate_id(args.issuer or operator.default_issuer(), "issuer")
    message = operator.command(action, issuer=issuer, robot_id=robot, reason=args.reason)
    keys = Keys(settings.fleet_name)
    with open_session(settings, "client") as session:
        outcome = operator.send_and_confirm(session, keys, message, max(args.wait, 0.0))
    target = f"robot {robot}" if robot else "the whole fleet"
    print(f"{action.value} sent to {target} (issuer {issuer}, seq {message.seq})", flush=True)
    for robot_id, seconds in outcome.confirmed.items():
        print(f"  {robot_id}: confirmed after {1e3 * seconds:.1f} ms")
    for robot_id in outcome.missing:
        print(f"  {robot_id}: NOT confirmed within {args.wait:g} s")
    if not outcome.confirmed and not outcome.missing:
        print("  no robot online (robots that join later do not get this command)")
    return 1 if outcome.missing and args.wait > 0 else 0
