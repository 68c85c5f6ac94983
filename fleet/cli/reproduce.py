"""``parkfleet reproduce``: the paper's Tables 5, 7, 9 (and the first scenario, parking)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from fleet.cli.options import add_json
from fleet.paper.reproduce import reproduce
from fleet.paper.scenarios import SCENARIOS


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "reproduce",
        help="run the paper's scenarios for both laws and print effort, distance, time",
        description="Runs the first scenario, comparative cases I-III and the parallel-parking "
        "experiment with the paper's gains (forward Euler, dt = 0.01 s).",
    )
    add_json(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    rows = reproduce()
    if args.json:
        print(json.dumps([row.model_dump() for row in rows]))
        return 0
    print(
        f"{'case':<8} {'law':<4} {'control effort':>15} {'distance (m)':>13} "
        f"{'time (s)':>9}  scenario"
    )
    for row in rows:
        print(
            f"{row.case:<8} {row.law:<4} {row.control_effort:>15.4f} {row.distance:>13.4f} "
            f"{row.time:>9.2f}  {SCENARIOS[row.case].title}"
        )
    return 0
