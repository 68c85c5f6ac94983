"""Reproduction of the paper's performance tables: laws (17)/(20) with the batch simulator,
and beside them the baselines (:mod:`fleet.paper.baselines`) in the same harness."""

from __future__ import annotations

import math

from pydantic import BaseModel

from fleet.core.simulate import PAPER_DT, BatchProblem, SimResult, simulate
from fleet.core.types import LAWS, Law
from fleet.paper.baselines import BASELINE_CASES, Controller, closed_loop, paper_baselines
from fleet.paper.scenarios import CASES, SCENARIOS, CaseName, Scenario
from fleet.paper.tables import PAPER_ROWS, RELATIVE_TOLERANCE, TIME_TOLERANCE, PaperRow


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


class ComparisonRow(BaseModel):
    """One controller on one comparative case, beside the paper's published row (if any).

    ``controller`` is ``"(17) ccw"``, ``"(20) cw"`` or a baseline's name.
    """

    case: CaseName
    controller: str
    control_effort: float
    distance: float
    time: float
    paper: PaperRow | None = None

    def deviation(self) -> dict[str, float] | None:
        """Relative effort and distance error, absolute time error [s], against the paper."""
        if self.paper is None:
            return None
        return {
            "control_effort": self.control_effort / self.paper.control_effort - 1.0,
            "distance": self.distance / self.paper.distance - 1.0,
            "time": self.time - self.paper.time,
        }

    def matches_paper(self) -> bool:
        """Within the targets: 2 % on effort and distance, 0.02 s on time."""
        dev = self.deviation()
        return dev is not None and (
            abs(dev["control_effort"]) <= RELATIVE_TOLERANCE
            and abs(dev["distance"]) <= RELATIVE_TOLERANCE
            and abs(dev["time"]) <= TIME_TOLERANCE + 1e-9
        )


LAW_LABELS: dict[Law, str] = {"ccw": "(17) ccw", "cw": "(20) cw"}


def run_baseline(
    scenario: Scenario, controller: Controller, record: bool = False, max_time: float = 120.0
) -> SimResult:
    """Run a baseline on one paper scenario in the shared harness (dt = 0.01 s)."""
    return closed_loop(
        controller,
        scenario.start,
        scenario.goal,
        scenario.tolerance,
        dt=PAPER_DT,
        max_time=max_time,
        profile=scenario.profile,
        record=record,
    )


def _row(case: CaseName, name: str, result: SimResult, paper: PaperRow | None) -> ComparisonRow:
    return ComparisonRow(
        case=case,
        controller=name,
        control_effort=float(result.control_effort[0]),
        distance=float(result.distance[0]),
        time=float(result.time[0]) if result.done[0] else math.nan,
        paper=paper,
    )


def compare(cases: tuple[CaseName, ...] = BASELINE_CASES) -> list[ComparisonRow]:
    """Laws (17) and (20) and every baseline on each case, with the paper's rows."""
    rows = []
    for case in cases:
        scenario = SCENARIOS[case]
        for law in LAWS:
            rows.append(_row(case, LAW_LABELS[law], run_scenario(scenario, law), None))
        for controller in paper_baselines(case):
            paper = PAPER_ROWS.get((case, controller.name))
            rows.append(_row(case, controller.name, run_baseline(scenario, controller), paper))
    return rows
