"""I/O edges shared by every process (the service, agents, simulators, benches, tests).

- :mod:`~fleet.io.settings`: the one ``Settings`` model (``PARKFLEET_*`` env, TOML file).
- :mod:`~fleet.io.transport`: the ``zenoh.Config`` builder, sessions, locators, endpoints.
- :mod:`~fleet.io.acl`: Zenoh access-control rules for a fleet.
- :mod:`~fleet.io.decoder`: payload decoding that drops and counts, callback guard.
- :mod:`~fleet.io.processes`: child ``parkfleet`` processes: command lines, ready lines,
  clean termination.
- :mod:`~fleet.io.trace`: lockstep trace files (every robot's true pose and mode per tick),
  written by ``parkfleet sim --trace``, read by ``parkfleet bench fleet``.
"""

__all__: list[str] = []
