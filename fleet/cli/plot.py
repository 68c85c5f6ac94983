"""``parkfleet plot``: one paper scenario drawn as in the paper's figures, or every
controller's path on one figure (``--compare``)."""

from __future__ import annotations

import argparse
from typing import Any

from fleet.core.types import LAWS
from fleet.paper.scenarios import CASES


def register(commands: Any, bench: Any) -> None:
    p = commands.add_parser(
        "plot",
        help="plot a paper scenario: path with oriented triangles, controls and errors (PNG)",
        description="Simulates one of the paper's scenarios with its gains (dt = 0.01 s) and "
        "writes a PNG: the path with the robot's orientation drawn as triangles, the "
        "controls u and omega, and the posture errors over time. With --compare: the paths "
        "of laws (17), (20) and the baselines (VFO, FT, Astolfi, Park & Kuipers) on one map.",
    )
    p.add_argument("case", choices=CASES, help="paper scenario")
    p.add_argument("--law", choices=LAWS, default="ccw", help="ccw = Eq. (17), cw = Eq. (20)")
    p.add_argument("--compare", action="store_true", help="every controller's path on one figure")
    p.add_argument(
        "-o", "--output", required=True, metavar="FILE.png", help="where to write the PNG"
    )
    p.add_argument(
        "--every", type=int, default=None, metavar="STEPS", help="steps between triangles"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # Imported here so other commands do not pay for matplotlib.
    from fleet.paper.plotting import plot_case, plot_compare, save_figure

    if args.every is not None and args.every < 1:
        raise ValueError("--every must be at least 1")
    fig = plot_compare(args.case) if args.compare else plot_case(args.case, args.law, args.every)
    print(save_figure(fig, args.output))
    return 0
