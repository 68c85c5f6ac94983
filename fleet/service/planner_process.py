"""The planner in a process of its own, so planning never holds the service's GIL.

:class:`PlannerProcess` is a :data:`~fleet.service.planner_worker.PlanFunction`: the
planner worker's thread calls it with the snapshot, it runs the pure planner
(:func:`fleet.core.planner.plan`) in one worker process and returns the plan. Waiting on the
pipe releases the GIL, so request threads, the tick and the Zenoh callbacks run on while it
plans. :func:`fleet.service.host.open_fleet` and :func:`fleet.service.standby.open_failover`
open it when ``Settings.planner_process`` is on (the default; off: the planner runs on the
worker thread).

* The worker is started by multiprocessing ``spawn`` (a fresh interpreter, never a bare
  fork: a forked child of a process with an open Zenoh session hangs) and warmed up at once
  (imports, the compiled step from numba's cache), so the first plan does not pay for it.
* The worker ends when the process that opened it ends, even SIGKILLed (no clean-up runs
  then): a thread of the worker waits on the spawn's parent sentinel (a pipe whose write
  end only the parent holds) and exits the worker when it reads EOF. Without it the worker
  would live on as an orphan forever: it waits for work on its call queue, whose write end
  it holds itself (a pickled ``multiprocessing.Queue`` carries both ends), so it never reads
  EOF there -- and it would keep the dead service's stdout and stderr open.
* A worker that dies (killed, out of memory) is restarted and the plan tried once more in
  the new one; every restart is counted (``planner_restarts``) and logged. A second crash in
  a row raises :class:`PlannerCrashed` (the planner worker counts it as a planner error and
  plans again on its next cycle).
* The snapshot and the plan cross the pipe pickled (frozen dataclasses and pydantic
  models): a few hundred microseconds for a 50-robot fleet.
"""

from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
import os
import threading
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from fleet.core.planner.model import Plan, PlanningSnapshot
from fleet.service.planner_worker import PlanFunction
from fleet.service.stats import Counters

_log = logging.getLogger(__name__)


class PlannerCrashed(RuntimeError):
    """The planner's process died twice in a row on one snapshot."""


def _exit_with_parent() -> None:
    """The worker's initializer: a daemon thread that ends the worker as soon as its parent
    (the service's process) is gone, however it went (module docstring)."""
    parent = multiprocessing.parent_process()
    if parent is None:  # not a multiprocessing child: nothing to watch
        return
    sentinel = parent.sentinel

    def watch() -> None:
        multiprocessing.connection.wait([sentinel])
        os._exit(1)  # no clean-up to run: the parent that needs the plans is gone

    threading.Thread(target=watch, name="planner-parent-watch", daemon=True).start()


def _warm_up() -> None:
    """Import the planner and load its compiled step in the worker process: plan one
    robot driving to one goal."""
    from fleet.core.params import Tolerance
    from fleet.core.planner import plan
    from fleet.core.planner.model import RobotSnapshot, TaskSnapshot
    from fleet.core.tasks import DEFAULT_GAINS, RobotStatus, TaskStatus

    robot = RobotSnapshot("warm", (0.0, 0.0, 0.0), RobotStatus.IDLE, True)
    task = TaskSnapshot(
        "warm-up", (1.0, 0.0, 0.0), "auto", dict(DEFAULT_GAINS), Tolerance(), TaskStatus.QUEUED, 0.0
    )
    plan(PlanningSnapshot(version=0, robots=(robot,), tasks=(task,)))
    start_parallel_kernel()


def start_parallel_kernel() -> None:
    """Defer the planner's kernel for large rollouts (:func:`fleet.core.step.
    defer_parallel_kernel`): the first large rollout of this process builds it
    (:func:`fleet.core.simulate.warm_parallel_kernel`: a minute's compile on a fresh
    install, then loaded from the cache) on a thread of its own; meanwhile large rollouts
    run on one thread, and no plan waits for the compile. A fleet too small for large
    rollouts never builds it."""
    from fleet.core.simulate import warm_parallel_kernel
    from fleet.core.step import defer_parallel_kernel

    def build() -> None:
        threading.Thread(target=warm_parallel_kernel, name="parallel-kernel", daemon=True).start()

    defer_parallel_kernel(build)


class PlannerProcess:
    """A plan function that runs ``plan_fn`` in a spawned process (module docstring).

    ``plan_fn`` must be picklable (a module-level function). :meth:`close` stops the
    process; a call after it raises ``RuntimeError``.
    """

    def __init__(self, plan_fn: PlanFunction, counters: Counters | None = None) -> None:
        self._plan_fn = plan_fn
        #: Where restarts are counted (``planner_restarts``); the service sets its own.
        self.counters = counters if counters is not None else Counters()
        self._context = multiprocessing.get_context("spawn")
        self._lock = threading.Lock()  # the pool reference (a restart replaces it)
        self._closed = False
        self._pool = self._start()

    def _start(self) -> ProcessPoolExecutor:
        pool = ProcessPoolExecutor(
            max_workers=1, mp_context=self._context, initializer=_exit_with_parent
        )
        try:
            pool.submit(_warm_up).result()
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        return pool

    def __call__(self, snapshot: PlanningSnapshot) -> Plan:
        for attempt in (1, 2):
            with self._lock:
                if self._closed:
                    raise RuntimeError("the planner process is closed")
                pool = self._pool
            try:
                return pool.submit(self._plan_fn, snapshot).result()
            except BrokenProcessPool:
                self._restart(pool)
                if attempt == 2:
                    raise PlannerCrashed(
                        f"the planner process died twice planning {len(snapshot.robots)} robots"
                    ) from None
        raise AssertionError("unreachable")

    def _restart(self, broken: ProcessPoolExecutor) -> None:
        """Replace a pool whose worker died (the planner worker's thread is the one caller;
        the new process is spawned and warmed up with no lock held)."""
        with self._lock:
            if self._closed or self._pool is not broken:
                return
        self.counters.add("planner_restarts")
        _log.error("the planner process died: restarting it")
        broken.shutdown(wait=False, cancel_futures=True)
        fresh = self._start()
        with self._lock:
            if not self._closed:
                self._pool, fresh = fresh, broken
        if fresh is not broken:
            fresh.shutdown(wait=True)  # closed meanwhile: not needed

    @property
    def pid(self) -> int | None:
        """The worker process's id (None before it started; tests kill it)."""
        with self._lock:
            processes = list(getattr(self._pool, "_processes", {}).values())
        return processes[0].pid if processes else None

    def close(self) -> None:
        """Stop the worker process (a plan under way is waited for); idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            pool = self._pool
        pool.shutdown(wait=True, cancel_futures=True)
