"""``parkfleet`` command line: the composition root of the project.

Each command lives in its own module exposing ``register(commands, bench)``; this module
only builds the parser and imports those modules (by name, lazily, so ``fleet`` keeps no
static dependency on the agent, simulator or API packages).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from fleet.cli.signals import interrupt_on_sigterm

#: Modules that register sub-commands, in help order.
COMMAND_MODULES: tuple[str, ...] = (
    "fleet.cli.reproduce",
    "fleet.cli.plot",
    "fleet.cli.tune",
    "fleet.cli.router",
    "fleet.cli.agent",
    "fleet.cli.sim",
    "fleet.cli.serve",
    "fleet.cli.demo",
    "fleet.cli.control",
    "fleet.cli.bench_sim",
    "fleet.cli.bench_zenoh",
    "fleet.cli.bench_api",
    "fleet.cli.bench_fleet",
    "fleet.cli.bench_estop",
    "fleet.cli.bench_on_state",
    "fleet.cli.bench_plan",
    "fleet.cli.bench_soak",
    "fleet.cli.bench_failover",
)
#: Commands whose module alone builds their parser: an operator's e-stop must not wait for
#: every other command's imports (numba, matplotlib: ~2 s) before it publishes.
URGENT_COMMANDS: dict[str, str] = {
    "estop": "fleet.cli.control",
    "pause": "fleet.cli.control",
    "resume": "fleet.cli.control",
}


def _command_of(argv: Sequence[str]) -> str | None:
    """The sub-command named in ``argv`` (after the global ``-v`` flags), if any."""
    for arg in argv:
        if arg in ("-v", "-vv", "--verbose"):
            continue
        return arg
    return None


def build_parser(modules: Sequence[str] = COMMAND_MODULES) -> argparse.ArgumentParser:
    """The ``parkfleet`` parser with the sub-commands of ``modules`` (default: all)."""
    parser = argparse.ArgumentParser(
        prog="parkfleet",
        description="Fleet service for self-parking robots (Lyapunov posture control over Zenoh).",
    )
    parser.add_argument(
        "-v", "--verbose", action="count", default=0, help="more logging (-vv: debug)"
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    bench_parser = commands.add_parser("bench", help="benchmarks that print numbers and ratios")
    bench = bench_parser.add_subparsers(dest="bench", metavar="BENCH", required=True)
    for name in modules:
        importlib.import_module(name).register(commands, bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    urgent = URGENT_COMMANDS.get(_command_of(argv) or "")
    args = build_parser((urgent,) if urgent else COMMAND_MODULES).parse_args(argv)
    level = logging.WARNING - 10 * min(int(args.verbose), 2)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        with interrupt_on_sigterm():  # SIGTERM unwinds like Ctrl-C: children, sessions closed
            return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (ValueError, FileNotFoundError, ConnectionError) as exc:
        print(f"parkfleet: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
