"""The paper (``shared/paper.txt``): its scenarios, their reproduction, what lies beyond.

- :mod:`~fleet.paper.scenarios`: the paper's initial postures, gains and tolerances.
- :mod:`~fleet.paper.tables`: its published VFO and FT rows (Tables 5, 7, 9).
- :mod:`~fleet.paper.reproduce`: runs them through the batch simulator, and the baselines
  beside them (``parkfleet reproduce [--baselines]``).
- :mod:`~fleet.paper.baselines`: VFO, finite-time, Astolfi and Park & Kuipers controllers in
  the simulator's harness.
- :mod:`~fleet.paper.tune`: gains by differential evolution (``parkfleet tune``).
- :mod:`~fleet.paper.switching_study`: the switching rule of :mod:`fleet.core.switching`
  against the fixed laws (``parkfleet reproduce --switching``).
- :mod:`~fleet.paper.plotting`: the paper's scenarios drawn (with :mod:`fleet.drawing`),
  every controller on one map, Pareto fronts (``parkfleet plot``, ``parkfleet tune``).
"""

__all__: list[str] = []
