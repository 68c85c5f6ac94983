"""Reproduction of the paper's performance tables with the batch simulator."""

from __future__ import annotations

import math

from pydantic import BaseModel

from fleet.core.simulate import PAPER_DT, BatchProblem, SimResult, simulate
from fleet.core.types import LAWS, Law
from fleet.paper.scenarios import CASES, SCENARIOS, CaseName, Scenario


class ReproductionRow(BaseModel):
    """Performance measures of one (case, law) run: Eq. (25) effort, distance [m], time [s]."""

    case: CaseName
    law: Law
    control_effort: float
    distance: float
    time: float


def run_scenario(
    scenario: Scenario, law: Law, record: bool = False, max_time: float = 120.0
) -> SimResult:
    """Simulate one paper scenario with the paper's gains for ``law`` at dt = 0.01 s."""
    problem = BatchProblem.build(
        scenario.start,
        scenario.goal,
        scenario.gains[law],
        law,
        tolerance=scenario.tolerance,
        profile=scenario.profile,
    )
    return simulate(problem, dt=PAPER_DT, max_time=max_time, record=record)


def reproduce(cases: tuple[CaseName, ...] = CASES) -> list[ReproductionRow]:
    """Rows for every requested case and both laws; time is NaN if tolerance was not reached."""
    rows = []
    for case in cases:
        for law in LAWS:
            result = run_scenario(SCENARIOS[case], law)
            rows.append(
                ReproductionRow(
                    case=case,
                    law=law,
                    control_effort=float(result.control_effort[0]),
                    distance=float(result.distance[0]),
                    time=float(result.time[0]) if result.done[0] else math.nan,
                )
            )
    return rows
