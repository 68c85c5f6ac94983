"""The fleet service: roster, task life cycle, dispatch and planning around a bus and a store.

- :mod:`~fleet.service.fleet_service`: :class:`FleetService`, the service shell.
- :mod:`~fleet.service.roster`: robots seen (liveliness + state stream).
- :mod:`~fleet.service.store`: the task store (SQLite, and an in-memory twin).
- :mod:`~fleet.service.bus`: the bus interface (and an in-memory twin for tests).
- :mod:`~fleet.service.zenoh_bus`: the bus on Zenoh.
"""

from fleet.service.fleet_service import FleetService

__all__ = ["FleetService"]
