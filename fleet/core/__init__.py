"""The pure core: no sockets, threads, clocks, files or logging (import-linter enforces it).

- :mod:`~fleet.core.types`: shared type names (``Law``, ``Posture``, arrays).
- :mod:`~fleet.core.params`: validated gains, tolerances, robot profile, avoidance.
- :mod:`~fleet.core.step`: THE closed-loop control step, compiled (numba): error (5),
  laws (17)/(20), Eq. (27) repulsion, saturation (Eq. 2), safety filter, Euler, stop rule;
  run by the agents, the simulated drive and the batch simulator.
- :mod:`~fleet.core.control`: law names, Eq. (2) on arrays, Lyapunov functions.
- :mod:`~fleet.core.simulate`: the batch closed-loop simulator (N robots at once).
- :mod:`~fleet.core.reference`: the plain-Python reference loop (test oracle).
- :mod:`~fleet.core.wire`: Zenoh key expressions and the versioned JSON messages.
- :mod:`~fleet.core.tasks`: task and robot models of the fleet service, its errors.
- :mod:`~fleet.core.goals`: goal validation (yard, obstacle zones, other goals).
- :mod:`~fleet.core.assignment`: optimal assignment of tasks to robots.
- :mod:`~fleet.core.planner`: who takes which task, with which law, when -- and who waits
  (clustered closed-loop rollouts of the control step).

Submodules are imported explicitly (``from fleet.core.step import step_robot``).
"""

__all__: list[str] = []
