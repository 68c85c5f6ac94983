"""How the switching rule (:mod:`fleet.core.switching`) compares with the fixed laws.

Two sets of trips, each driven three ways -- law (17) alone, law (20) alone, and the
switching rule -- in the same simulator:

* the paper's scenarios with their gains, tolerances and unlimited robot at dt = 0.01 s;
* random yard trips (:func:`fleet.paper.tune.yard_trips`) with the service's default gains,
  the 20 rad/s wheel limit and the fleet's tolerance at the agents' 50 Hz.

The figure of merit is the path length relative to the better fixed law for that trip
(1 = as short, below 1 = shorter).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel

from fleet.core.params import RobotProfile
from fleet.core.simulate import PAPER_DT
from fleet.core.switching import CHECKPOINTS, SwitchingRun, switching_run
from fleet.core.tasks import DEFAULT_GAINS
from fleet.core.types import LAWS
from fleet.paper.scenarios import CASES, SCENARIOS, CaseName
from fleet.paper.tune import YARD_DT, YARD_TOLERANCE, yard_trips


class CaseSwitching(BaseModel):
    """One paper scenario: distances [m] of both fixed laws and of the switching rule."""

    case: CaseName
    ccw: float
    cw: float
    switching: float
    laws: list[str]  # the rule's law on each segment, in order
    switch_times: list[float]  # [s]


class YardSwitching(BaseModel):
    """Random yard trips: distribution of switching / better-fixed path length."""

    trips: int
    seed: int
    arrived: float  # fraction of trips the rule completed
    mean_ratio: float
    percentiles: dict[str, float]  # "p5", "p50", "p95" of the ratio
    worst_ratio: float
    best_ratio: float
    shorter: float  # fraction of trips strictly shorter than the better fixed law
    switched: float  # fraction of trips with at least one switch
    mean_distance: dict[str, float]  # [m] "ccw", "cw", "best fixed", "switching"
    worst_trip: list[list[float]]  # [start, goal] of the trip with the largest ratio


def _segments(run: SwitchingRun, i: int) -> tuple[list[str], list[float]]:
    segs = run.segments[i]
    return [s.law for s in segs], [s.start_time for s in segs[1:]]


def paper_cases(
    cases: tuple[CaseName, ...] = CASES, checkpoints: int = CHECKPOINTS
) -> list[CaseSwitching]:
    """The switching rule on each paper scenario with the paper's gains."""
    rows = []
    for case in cases:
        sc = SCENARIOS[case]
        run = switching_run(
            sc.start,
            sc.goal,
            sc.gains,
            sc.tolerance,
            sc.profile,
            dt=PAPER_DT,
            max_time=120.0,
            checkpoints=checkpoints,
        )
        laws, times = _segments(run, 0)
        rows.append(
            CaseSwitching(
                case=case,
                ccw=float(run.fixed["ccw"].distance[0]),
                cw=float(run.fixed["cw"].distance[0]),
                switching=float(run.distance[0]),
                laws=laws,
                switch_times=times,
            )
        )
    return rows


def yard(trips: int = 1000, seed: int = 7, checkpoints: int = CHECKPOINTS) -> YardSwitching:
    """The switching rule on ``trips`` random yard trips with the service's default gains."""
    starts, goals = yard_trips(trips, seed)
    run = switching_run(
        starts,
        goals,
        DEFAULT_GAINS,
        YARD_TOLERANCE,
        RobotProfile(),
        dt=YARD_DT,
        max_time=200.0,
        checkpoints=checkpoints,
    )
    best = run.best_fixed_distance()
    ok = np.isfinite(best)
    ratio = run.distance[ok] / best[ok]
    worst = int(np.flatnonzero(ok)[int(np.argmax(ratio))])
    return YardSwitching(
        trips=trips,
        seed=seed,
        arrived=float(run.done.mean()),
        mean_ratio=float(ratio.mean()),
        percentiles={f"p{q}": float(np.percentile(ratio, q)) for q in (5, 50, 95)},
        worst_ratio=float(ratio.max()),
        best_ratio=float(ratio.min()),
        shorter=float((ratio < 1.0).mean()),
        switched=float((run.switches > 0).mean()),
        mean_distance={
            **{law: float(run.fixed[law].distance[ok].mean()) for law in LAWS},
            "best fixed": float(best[ok].mean()),
            "switching": float(run.distance[ok].mean()),
        },
        worst_trip=[starts[worst].tolist(), goals[worst].tolist()],
    )
