"""``parkfleet tune``: gains for law (17) or (20) found by differential evolution."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from fleet.cli.options import add_json, positive_float
from fleet.core.types import LAWS
from fleet.paper.scenarios import CASES
from fleet.paper.tune import (
    CASE_WEIGHTS,
    YARD_MAX_KX,
    YARD_WEIGHTS,
    TuneResult,
    Weights,
    case_target,
    tune,
    yard_target,
)

TARGETS: tuple[str, ...] = (*CASES, "yard")


def _non_negative(text: str) -> float:
    value = float(text)
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "tune",
        help="search gains for a paper case or the yard (differential evolution)",
        description="Searches (kx, ky, ktheta) for one law by scipy's differential evolution, "
        "every generation simulated in one batch. The cost is a weighted sum of mean "
        "control effort (Eq. 25), distance, time and turns (the robot's whole rotation, in "
        "revolutions) over the target's trips; the robot has "
        "the fleet's 20 rad/s wheel limit. CASE is a paper scenario (its start, goal and "
        "tolerance, dt = 0.01 s; the paper's gains are the reference) or 'yard': random "
        "yard trips at the agents' 50 Hz, time first with every whole turn priced at 2 s "
        "(the service's default gains).",
    )
    p.add_argument("case", choices=TARGETS, metavar="CASE", help=" | ".join(TARGETS))
    p.add_argument("--law", choices=LAWS, required=True, help="ccw = Eq. (17), cw = Eq. (20)")
    for name, unit, c, y in (
        ("effort", "(Eq. 25)", CASE_WEIGHTS.effort, YARD_WEIGHTS.effort),
        ("distance", "[1/m]", CASE_WEIGHTS.distance, YARD_WEIGHTS.distance),
        ("time", "[1/s]", CASE_WEIGHTS.time, YARD_WEIGHTS.time),
        ("turns", "[1/revolution]", CASE_WEIGHTS.turns, YARD_WEIGHTS.turns),
    ):
        p.add_argument(
            f"--w-{name}",
            type=_non_negative,
            metavar="W",
            help=f"weight of the {name} {unit} (default: case {c:g}, yard {y:g})",
        )
    p.add_argument("--generations", type=int, default=60, help="at most this many (60)")
    p.add_argument("--popsize", type=int, default=15, help="scipy's multiplier (15)")
    p.add_argument("--seed", type=int, default=0, help="search seed (0)")
    p.add_argument("--trips", type=int, default=200, help="yard: random trips scored (200)")
    p.add_argument(
        "--max-kx",
        type=positive_float,
        help="yard: largest kx [1/s] searched (default Table 1's kx of the law, "
        f"{YARD_MAX_KX['ccw']:g} ccw / {YARD_MAX_KX['cw']:g} cw: keeps Eq. 27's standoffs)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="FILE.png",
        help="Pareto plot (default: tune-CASE-LAW.png)",
    )
    add_json(p)
    p.set_defaults(func=run)


def _weights(args: argparse.Namespace, default: Weights) -> Weights:
    return Weights(
        effort=default.effort if args.w_effort is None else args.w_effort,
        distance=default.distance if args.w_distance is None else args.w_distance,
        time=default.time if args.w_time is None else args.w_time,
        turns=default.turns if args.w_turns is None else args.w_turns,
    )


def _report(result: TuneResult, plot: Path) -> dict[str, object]:
    return {
        "target": result.target.name,
        "law": result.target.law,
        "best": result.best.model_dump(),
        "best_scores": result.best_scores,
        "reference": None
        if result.target.reference is None
        else result.target.reference.model_dump(),
        "reference_scores": result.reference_scores,
        "beats_reference": result.beats_reference,
        "generations": result.generations,
        "candidates": int(result.evaluated_gains.shape[0]),
        "plot": str(plot),
    }


def run(args: argparse.Namespace) -> int:
    if args.generations < 1 or args.popsize < 2 or args.trips < 1:
        raise ValueError("--generations >= 1, --popsize >= 2 and --trips >= 1 are required")
    if args.case == "yard":
        target = yard_target(
            args.law, trips=args.trips, weights=_weights(args, YARD_WEIGHTS), max_kx=args.max_kx
        )
    else:
        target = case_target(args.case, args.law, weights=_weights(args, CASE_WEIGHTS))
    result = tune(target, seed=args.seed, popsize=args.popsize, generations=args.generations)
    # Imported here so the search does not pay for matplotlib until it draws.
    from fleet.paper.plotting import plot_pareto, save_figure

    out = args.output or Path(f"tune-{args.case}-{args.law}.png")
    save_figure(plot_pareto(result), out)
    report = _report(result, out)
    if args.json:
        print(json.dumps(report))
        return 0
    best, ref = result.best, result.target.reference
    print(f"target {target.name}, law {target.law}: {target.trips} trip(s), dt = {target.dt} s")
    print(f"best gains      kx={best.kx:.4g} ky={best.ky:.4g} ktheta={best.ktheta:.4g}")
    _scores("best", result.best_scores)
    if ref is not None and result.reference_scores is not None:
        print(f"paper's gains   kx={ref.kx:.4g} ky={ref.ky:.4g} ktheta={ref.ktheta:.4g}")
        _scores("paper", result.reference_scores)
        verdict = "beats" if result.beats_reference else "does not beat"
        print(f"the best {verdict} the paper's gains on both effort and distance")
    print(out)
    return 0


def _scores(label: str, s: dict[str, float]) -> None:
    print(
        f"  {label:<6} effort {s['effort']:.4f}  distance {s['distance']:.4f} m  "
        f"time {s['time']:.2f} s  turns {s['turns']:.2f} rev  arrived {s['done']:.0%}  "
        f"cost {s['cost']:.4f}"
    )
