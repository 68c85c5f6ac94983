"""The one place that assembles a running fleet from settings: :func:`open_fleet`.

``parkfleet serve`` (through the API's lifespan, :mod:`api.app`) and every benchmark that
runs the real service (:mod:`fleet.bench.fleet`, :mod:`fleet.bench.zenoh`) open the fleet
here, so they run the same thing in the same order:

0. the planner's own process (``Settings.planner_process``, on by default:
   :mod:`fleet.service.planner_process`), spawned first (multiprocessing ``spawn``, a fresh
   interpreter: safe beside an open Zenoh session, which a fork is not);
1. the Zenoh session in ``router`` mode (the router the robots connect to), unless one is
   given (a benchmark sharing one router between runs, a test's client session);
2. the task store, from ``store`` -- the store choice is this one parameter
   (:data:`StoreFactory`; :func:`sqlite_store` by default, the file
   ``Settings.db_path``, ``<data_dir>/parkfleet.db``);
3. the Zenoh bus (optionally wrapped, e.g. to time it);
4. the :class:`~fleet.service.fleet_service.FleetService`, started;
5. the heap trimmer (:mod:`fleet.io.heap`, ``heap_trim_interval_s``).

Everything is closed in reverse order however opening or the body ends (an unclosed Zenoh
session hangs interpreter exit).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass

import zenoh

from fleet.core.planner import plan
from fleet.core.wire import Keys
from fleet.io.heap import HeapTrimmer
from fleet.io.settings import Settings
from fleet.io.transport import listening_locators, open_session
from fleet.service.bus import FleetBus
from fleet.service.clock import Clock
from fleet.service.fleet_service import FleetService
from fleet.service.planner_process import PlannerProcess, start_parallel_kernel
from fleet.service.store import SqliteTaskStore, TaskStore
from fleet.service.zenoh_bus import ZenohFleetBus

__all__ = ["RunningFleet", "StoreFactory", "open_fleet", "sqlite_store"]

#: Opens the fleet's task store from its settings; :func:`open_fleet` closes it.
StoreFactory = Callable[[Settings], TaskStore]


def sqlite_store(settings: Settings) -> TaskStore:
    """The embedded default store: SQLite at ``settings.db_path`` (its folder created)."""
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    return SqliteTaskStore(settings.db_path)


@dataclass(frozen=True)
class RunningFleet:
    """A fleet opened by :func:`open_fleet`: its parts, open until the ``with`` ends."""

    session: zenoh.Session
    store: TaskStore
    bus: FleetBus
    service: FleetService
    #: Zenoh endpoints the router really listens on (a ``:0`` port resolved); empty when
    #: the session was given (its owner knows them).
    locators: list[str]


@contextmanager
def open_fleet(
    settings: Settings,
    *,
    store: StoreFactory = sqlite_store,
    session: zenoh.Session | None = None,
    wrap_bus: Callable[[FleetBus], FleetBus] | None = None,
    clock: Clock | None = None,
) -> Iterator[RunningFleet]:
    """Open router session, store, bus, service and heap trimmer; close them in reverse.

    ``session``: use this open session (not closed here) instead of opening a router.
    ``store``: the store choice (SQLite at ``settings.db_path`` by default).
    ``wrap_bus``: wraps the Zenoh bus before the service gets it (benchmarks time it).
    """
    with ExitStack() as stack:
        planner: PlannerProcess | None = None
        if settings.planner_process:
            planner = PlannerProcess(plan)  # builds its kernels in its own process
            stack.callback(planner.close)  # after the service stopped planning
        else:
            start_parallel_kernel()  # the planner plans here, on the service's threads
        locators: list[str] = []
        if session is None:
            session = open_session(settings, "router")
            stack.callback(session.close)
            locators = listening_locators(session)
        tasks = store(settings)
        stack.callback(tasks.close)
        bus: FleetBus = ZenohFleetBus(session, Keys(settings.fleet_name))
        stack.callback(bus.close)
        if wrap_bus is not None:
            bus = wrap_bus(bus)
        service = FleetService(settings, bus, tasks, clock=clock, planner=planner)
        stack.callback(service.close)
        service.start()
        trimmer = HeapTrimmer(settings.heap_trim_interval_s)
        stack.callback(trimmer.close)
        trimmer.start()
        yield RunningFleet(session, tasks, bus, service, locators)
