"""The paper (``shared/paper.txt``): its scenarios, their reproduction and the figures.

- :mod:`~fleet.paper.scenarios`: the paper's initial postures, gains and tolerances.
- :mod:`~fleet.paper.reproduce`: runs them through the batch simulator (``parkfleet reproduce``).
- :mod:`~fleet.paper.plotting`: paths and signals as in the paper's figures (``parkfleet plot``).
"""

__all__: list[str] = []
