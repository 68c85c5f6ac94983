"""``parkfleet reproduce``: the paper's Tables 5, 7, 9 (and the first scenario, parking);
``--baselines`` adds VFO, FT, Astolfi and Park & Kuipers beside laws (17) and (20)."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

from fleet.cli.options import add_json
from fleet.paper.reproduce import ComparisonRow, compare, reproduce
from fleet.paper.scenarios import SCENARIOS


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "reproduce",
        help="run the paper's scenarios for both laws and print effort, distance, time",
        description="Runs the first scenario, comparative cases I-III and the parallel-parking "
        "experiment with the paper's gains (forward Euler, dt = 0.01 s). With --baselines: "
        "comparative cases I-III for laws (17), (20) and the baselines (VFO, FT, Astolfi, "
        "Park & Kuipers) in the same harness, beside the paper's VFO and FT rows.",
    )
    mode = p.add_mutually_exclusive_group()
    mode.add_argument(
        "--baselines",
        action="store_true",
        help="compare with VFO, FT (Tables 2, 3, 5, 7, 9), Astolfi and Park & Kuipers",
    )
    mode.add_argument(
        "--switching",
        action="store_true",
        help="the switching rule (fleet.core.switching) against both fixed laws: the paper's "
        "cases and random yard trips",
    )
    p.add_argument("--trips", type=int, default=1000, help="--switching: random yard trips (1000)")
    add_json(p)
    p.set_defaults(func=run)


def _print_comparison(rows: list[ComparisonRow]) -> None:
    print(
        f"{'case':<5} {'controller':<13} {'effort':>9} {'dist (m)':>9} {'time (s)':>9}  "
        f"{'paper: effort':>13} {'dist':>8} {'time':>6}  deviation (effort, dist, time)"
    )
    for row in rows:
        line = (
            f"{row.case:<5} {row.controller:<13} {row.control_effort:>9.4f} "
            f"{row.distance:>9.4f} {row.time:>9.2f}"
        )
        dev = row.deviation()
        if row.paper is not None and dev is not None:
            mark = "match" if row.matches_paper() else "no match"
            line += (
                f"  {row.paper.control_effort:>13.4f} {row.paper.distance:>8.4f} "
                f"{row.paper.time:>6.2f}  {dev['control_effort']:+.1%}, "
                f"{dev['distance']:+.1%}, {dev['time']:+.2f} s ({mark})"
            )
        print(line)
    print("Targets: 2 % on effort and distance, 0.02 s on time; docs/paper.md explains the gaps.")


def _switching(args: argparse.Namespace) -> int:
    from fleet.paper.switching_study import paper_cases, yard

    if args.trips < 1:
        raise ValueError("--trips must be at least 1")
    cases, trips = paper_cases(), yard(trips=args.trips)
    if args.json:
        print(json.dumps({"cases": [c.model_dump() for c in cases], "yard": trips.model_dump()}))
        return 0
    print(f"{'case':<8} {'ccw (m)':>9} {'cw (m)':>9} {'switching (m)':>14}  laws (switch times)")
    for c in cases:
        times = ", ".join(f"{t:.2f} s" for t in c.switch_times)
        print(
            f"{c.case:<8} {c.ccw:>9.4f} {c.cw:>9.4f} {c.switching:>14.4f}  "
            f"{' -> '.join(c.laws)}" + (f" ({times})" if times else "")
        )
    y = trips
    p = y.percentiles
    print(
        f"yard: {y.trips} random trips (seed {y.seed}), default gains, 20 rad/s, 50 Hz: "
        f"arrived {y.arrived:.1%}, switched {y.switched:.1%}, shorter {y.shorter:.1%}"
    )
    print(
        f"  path / better fixed law: mean {y.mean_ratio:.4f}, p5 {p['p5']:.4f}, "
        f"p50 {p['p50']:.4f}, p95 {p['p95']:.4f}, best {y.best_ratio:.4f}, "
        f"worst {y.worst_ratio:.6f}"
    )
    d = y.mean_distance
    print(
        f"  mean distance: ccw {d['ccw']:.3f} m, cw {d['cw']:.3f} m, better fixed "
        f"{d['best fixed']:.3f} m, switching {d['switching']:.3f} m"
    )
    return 0


def run(args: argparse.Namespace) -> int:
    if args.switching:
        return _switching(args)
    if args.baselines:
        comparison = compare()
        if args.json:
            print(json.dumps([row.model_dump() for row in comparison]))
        else:
            _print_comparison(comparison)
        return 0
    rows = reproduce()
    if args.json:
        print(json.dumps([row.model_dump() for row in rows]))
        return 0
    print(
        f"{'case':<8} {'law':<4} {'control effort':>15} {'distance (m)':>13} "
        f"{'time (s)':>9}  scenario"
    )
    for row in rows:
        time = "-" if math.isnan(row.time) else f"{row.time:.2f}"
        print(
            f"{row.case:<8} {row.law:<4} {row.control_effort:>15.4f} {row.distance:>13.4f} "
            f"{time:>9}  {SCENARIOS[row.case].title}"
        )
    return 0
