"""Simulated robots standing in for hardware, on one machine (tests, the demo, benches).

- :mod:`~sim_agent.drive`: :class:`SimDrive`, a kinematic unicycle implementing the
  agent's Drive; ``make_drive`` is ``parkfleet agent --drive sim``.
- :mod:`~sim_agent.fleet`: :class:`SimFleet`, N full robot agents sharing one Zenoh
  session, ticked in lockstep (``--time-scale``); spawn layouts.
- :mod:`~sim_agent.disturbances`: a real robot's imperfections (``DisturbedDrive``) and a
  Wi-Fi link's between robots (``DelayedLink``), ``--disturbed``.
- :mod:`~sim_agent.robots`: :class:`SimRobots`, the one recipe for a run's drives and link
  from a seed (SimFleet's and the bench's navground peers').

Run a fleet with ``parkfleet sim --robots N``.
"""

from sim_agent.drive import SimDrive, make_drive
from sim_agent.fleet import SimFleet, Spawn, spawn_layout

__all__ = ["SimDrive", "SimFleet", "Spawn", "make_drive", "spawn_layout"]
