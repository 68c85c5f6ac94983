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
from typing import Any

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
#: Packages that only some installs have -> the extra that brings them (``pyproject.toml``).
EXTRA_OF: dict[str, str] = {
    "fastapi": "server",
    "uvicorn": "server",
    "prometheus_client": "server",
    "httpx": "bench",
    "aiohttp": "bench",
    "scipy": "server",
    "shapely": "server",  # the route graph, narrow passages (fleet/core/planner/)
    "networkx": "server",
    "uvloop": "server",
    "httptools": "server",
    "matplotlib": "bench",
    "navground": "bench",
    "psycopg": "postgres",  # serve --store postgresql://...; bench failover
}
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
        try:
            importlib.import_module(name).register(commands, bench)
        except ModuleNotFoundError as exc:
            extra = _missing_extra(exc)
            if extra is None:
                raise
            _register_unavailable(commands, bench, name, _install_hint(exc, extra))
    return parser


def _missing_extra(exc: ModuleNotFoundError) -> str | None:
    """The extra that would bring the missing module, if it is one an install may lack."""
    top = (exc.name or "").split(".")[0]
    return EXTRA_OF.get(top)


def _install_hint(exc: ModuleNotFoundError, extra: str) -> str:
    return f"needs parkfleet[{extra}] (no module {exc.name} here): pip install 'parkfleet[{extra}]'"


def _register_unavailable(commands: Any, bench: Any, module: str, hint: str) -> None:
    """A command whose module needs a package this install lacks (a robot's ``robot``
    extra has no server or bench packages): it stays listed, and says what to install."""
    short = module.rsplit(".", 1)[-1]
    parent, name = (bench, short[6:]) if short.startswith("bench_") else (commands, short)
    p = parent.add_parser(name, help=hint, description=hint)
    p.set_defaults(func=lambda _args: _unavailable(hint))


def _unavailable(hint: str) -> int:
    print(f"parkfleet: error: this command {hint}", file=sys.stderr)
    return 2


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
    except ModuleNotFoundError as exc:
        extra = _missing_extra(exc)
        if extra is None:
            raise
        return _unavailable(_install_hint(exc, extra))
    except (ValueError, FileNotFoundError, ConnectionError) as exc:
        print(f"parkfleet: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
