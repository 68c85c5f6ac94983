"""``parkfleet estop | pause | resume``: operator commands straight to the robots over Zenoh.

The command opens its own client session to the fleet's router and publishes a
``ControlCommand`` on the key every agent obeys (``fleet.core.wire``), so it works while the
fleet service is down. The first publication goes out at once; the robots concerned
(``--robot ID``, or every robot of the fleet online: ``--fleet NAME``, default the settings'
``fleet_name``) are discovered meanwhile. It re-sends until every one of them reports a
state that obeys, or ``--wait`` passes, and prints who confirmed and how fast.

Exit codes: 0 every robot concerned confirmed (or ``--wait 0``: sent once, not confirmed);
1 a robot did not confirm (named on stderr), or none did (no robot of the fleet online: a
wrong ``--fleet``?), or the query for who is online did not complete within the wait;
2 bad arguments.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from fleet.cli.options import add_config, add_connect, add_fleet
from fleet.core.wire import ControlAction, Keys, validate_id
from fleet.io import operator
from fleet.io.settings import load_settings
from fleet.io.transport import open_session

HELP = {
    "estop": "emergency stop: wheels to zero at once, tasks held, latched until --release",
    "pause": "pause: robots stop and keep their tasks until resume",
    "resume": "resume paused robots (an e-stopped robot needs estop --release)",
}
EPILOG = (
    "exit codes: 0 every robot concerned confirmed (--wait 0: sent once, not confirmed); "
    "1 some robot did not confirm (named), or none did (no robot of the fleet online: "
    "check --fleet); 2 bad arguments"
)


def register(commands: Any, bench: Any) -> None:
    for name, text in HELP.items():
        p = commands.add_parser(
            name,
            help=text,
            description=f"{text[0].upper()}{text[1:]}. Publishes on the Zenoh key the robots "
            "obey directly (works without the fleet service) and waits until they confirm.",
            epilog=EPILOG,
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
        add_fleet(p)
        add_connect(p)
        add_config(p)
        p.set_defaults(func=run, action=name)


def run(args: argparse.Namespace) -> int:
    fleet = None if args.fleet is None else validate_id(args.fleet, "fleet name")
    settings = load_settings(args.config, connect=args.connect, fleet_name=fleet)
    keys = Keys(settings.fleet_name)
    action = ControlAction(args.action)
    if action is ControlAction.ESTOP and args.release:
        action = ControlAction.RELEASE
    robot = None if args.robot is None else validate_id(args.robot)
    issuer = validate_id(args.issuer or operator.default_issuer(), "issuer")
    wait = max(args.wait, 0.0)
    with open_session(settings, "client") as session:
        # Stamped once the session is open: the stamp is the first put's time (to a few µs).
        message = operator.command(action, issuer=issuer, robot_id=robot, reason=args.reason)
        outcome = operator.send_and_confirm(session, keys, message, wait)
    target = f"robot {robot}" if robot else "the whole fleet"
    print(
        f"{action.value} sent to {target} of fleet {keys.fleet} "
        f"(issuer {issuer}, seq {message.seq})",
        flush=True,
    )
    for robot_id, seconds in outcome.confirmed.items():
        print(f"  {robot_id}: confirmed after {1e3 * seconds:.1f} ms")
    if wait == 0:
        print("  not confirmed (--wait 0)")
        return 0
    for robot_id in outcome.missing:
        print(f"  {robot_id}: NOT confirmed within {wait:g} s")
    if outcome.missing:
        print(
            f"parkfleet {args.action}: not confirmed by {', '.join(outcome.missing)}",
            file=sys.stderr,
        )
        return 1
    if not outcome.confirmed:
        if outcome.discovered:
            why = f"no robot of fleet {keys.fleet} is online; nothing confirmed"
        else:
            why = f"no robot of fleet {keys.fleet} answered within {wait:g} s; nothing confirmed"
        print(f"parkfleet {args.action}: {why}", file=sys.stderr)
        return 1
    if not outcome.discovered:  # who else is online is unknown: no claim that all stopped
        print(
            f"parkfleet {args.action}: the query for the robots of fleet {keys.fleet} online "
            f"did not complete within {wait:g} s; others may not have confirmed",
            file=sys.stderr,
        )
        return 1
    return 0
