"""The controllers the paper compares against, and two that users know, in one harness.

- :mod:`~fleet.paper.baselines.harness`: the closed loop (unicycle, forward Euler, the stop
  rule and metrics of :mod:`fleet.core.simulate`) for any :class:`Controller`.
- :mod:`~fleet.paper.baselines.vfo`: VFO, Michałek & Kozłowski 2010 (the paper's [23]).
- :mod:`~fleet.paper.baselines.ft`: two-phase finite-time control after Thomas et al.
  2016 (the paper's [21]; a reconstruction, see its docstring).
- :mod:`~fleet.paper.baselines.polar`: Aicardi/Astolfi polar law (PythonRobotics).
- :mod:`~fleet.paper.baselines.ego_polar`: Park & Kuipers ego-polar law (Nav2 graceful).

:func:`paper_baselines` gives them with the paper's gains for a comparative case
(Tables 2 and 3 for VFO and FT; the others keep their library defaults).
"""

from __future__ import annotations

from fleet.paper.baselines.ego_polar import EgoPolar
from fleet.paper.baselines.ft import FiniteTime
from fleet.paper.baselines.harness import Controller, closed_loop
from fleet.paper.baselines.polar import PolarPose
from fleet.paper.baselines.vfo import VFO
from fleet.paper.scenarios import SCENARIOS, CaseName

#: Table 2: VFO gains (k1, kp, eta) per comparative case.
VFO_GAINS: dict[CaseName, VFO] = {
    "I": VFO(k1=10.0, kp=5.0, eta=3.0),
    "II": VFO(k1=1.0, kp=4.0, eta=0.1),
    "III": VFO(k1=1.0, kp=8.0, eta=1.0),
}

#: Table 3: FT gains (K1, K2, k1, k2, alpha1, alpha2, T) per comparative case.
FT_GAINS: dict[CaseName, FiniteTime] = {
    "I": FiniteTime(K1=2.0, K2=2.0, k1=2.0, k2=2.0, alpha1=1.02, alpha2=0.5, T=2.52),
    "II": FiniteTime(K1=1.5, K2=1.1, k1=3.0, k2=2.0, alpha1=2 / 3, alpha2=0.5, T=2.0),
    "III": FiniteTime(K1=3.0, K2=2.0, k1=3.0, k2=2.0, alpha1=0.9, alpha2=0.5, T=2.1),
}

BASELINE_CASES: tuple[CaseName, ...] = ("I", "II", "III")


def paper_baselines(case: CaseName) -> list[Controller]:
    """VFO and FT with the paper's gains for ``case`` (comparative cases only), then the
    Astolfi and Park & Kuipers laws with their library defaults."""
    controllers: list[Controller] = []
    if case in VFO_GAINS:
        controllers += [VFO_GAINS[case], FT_GAINS[case]]
    final = SCENARIOS[case].tolerance.position
    controllers += [PolarPose(), EgoPolar(final_radius=final)]
    return controllers


__all__ = [
    "BASELINE_CASES",
    "FT_GAINS",
    "VFO",
    "VFO_GAINS",
    "Controller",
    "EgoPolar",
    "FiniteTime",
    "PolarPose",
    "closed_loop",
    "paper_baselines",
]
