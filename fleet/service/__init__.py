"""The fleet service: roster, task ledger, planning and dispatch around a bus and a store.

- :mod:`~fleet.service.fleet_service`: :class:`FleetService`, the thin shell (one lock, threads,
  bus callbacks, tick), with its roles :mod:`~fleet.service.submission` (tasks, bays),
  :mod:`~fleet.service.operators` (operator controls) and :mod:`~fleet.service.planning`
  (planner glue) on the state declared in :mod:`~fleet.service.service_state`.
- :mod:`~fleet.service.ledger`: the task ledger (pure): indexes, transitions returning effects.
- :mod:`~fleet.service.effects`: effects as data; :mod:`~fleet.service.outbox` applies them
  outside the lock, stored before announced.
- :mod:`~fleet.service.planner_worker`: plans on its own thread; :mod:`~fleet.service.snapshot`
  builds its input; :mod:`~fleet.service.horizon` holds the re-plan triggers.
- :mod:`~fleet.service.roster`: robots seen (liveliness + state stream), retention.
- :mod:`~fleet.service.paths`: recorded task paths, bounded.
- :mod:`~fleet.service.clock`: the one clock (monotonic deadlines, wall stamps).
- :mod:`~fleet.service.stats`: counters and the planning-latency window.
- :mod:`~fleet.service.store`: the task store (SQLite, and an in-memory twin).
- :mod:`~fleet.service.bus`: the bus interface (and an in-memory twin for tests).
- :mod:`~fleet.service.zenoh_bus`: the bus on Zenoh.
"""

from fleet.service.fleet_service import FleetService

__all__ = ["FleetService"]
