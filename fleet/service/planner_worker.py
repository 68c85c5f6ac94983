"""The planner worker: plans on its own thread, so resends and timeouts never wait for it.

One cycle (:meth:`PlannerWorker.step`):

1. ``take()`` -- the service copies what the plan depends on under its lock (cheap) and
   returns a :class:`~fleet.service.snapshot.PlanInput`, or None when there is nothing to
   decide;
2. ``plan_fn(snapshot)`` -- the pure planner (:func:`fleet.core.planner.plan`), run with
   **no lock held** (it may take a while);
3. ``apply(plan, input)`` -- the service applies the plan through its ledger under its lock;
   decisions on tasks that changed meanwhile are dropped there (a stale plan is rebased).

Re-planning is receding-horizon: :meth:`PlannerWorker.request` (cheap, from any thread)
asks for a cycle with a reason (tasks arrived or finished, robots joined or were lost, a
robot left its predicted corridor, two robots came too close ...), and the thread also
plans every ``period_s`` on its own. Requests that arrive while a plan runs are served by
one more cycle right after it. A burst of submissions is planned together: after a
``burst`` request the worker waits until none came for ``settle_s`` [s, monotonic] (at most
``settle_max_s``).

Without a thread (the service's single-threaded test mode) the caller runs
:meth:`PlannerWorker.step` itself.

**The plans log**: with the ``fleet.plans`` logger at DEBUG, every plan applied is one
JSON line there -- the wall-clock time it was made [s, epoch], its planning time
``took_s`` [s, to the µs], the snapshot's robot count and
:meth:`~fleet.core.planner.model.Plan.summary` (``parkfleet bench fleet --traces`` keeps
it per run in ``plans.jsonl``).
"""

from __future__ import annotations

import json
import logging
import math
import threading
from collections.abc import Callable

from fleet.core.planner.model import Plan, PlanningSnapshot
from fleet.service.clock import Clock
from fleet.service.snapshot import PlanInput
from fleet.service.stats import Counters, LatencyWindow

_log = logging.getLogger(__name__)
#: one JSON line per plan at DEBUG (module docstring)
plans_log = logging.getLogger("fleet.plans")

PlanFunction = Callable[[PlanningSnapshot], Plan]

#: A burst of submissions is planned together once none came for this long [s, monotonic]
#: (at most ``DISPATCH_SETTLE_MAX_S`` after the first).
DISPATCH_SETTLE_S = 0.05
DISPATCH_SETTLE_MAX_S = 0.5


class PlannerWorker:
    """Runs snapshot -> plan -> apply cycles on request and periodically (module docstring)."""

    def __init__(
        self,
        take: Callable[[], PlanInput | None],
        plan_fn: PlanFunction,
        apply: Callable[[Plan, PlanInput], None],
        clock: Clock,
        counters: Counters,
        period_s: float = 2.0,
        settle_s: float = DISPATCH_SETTLE_S,
        settle_max_s: float = DISPATCH_SETTLE_MAX_S,
    ) -> None:
        self._take = take
        self._plan_fn = plan_fn
        self._apply = apply
        self._clock = clock
        self._counters = counters
        self.period_s = period_s
        self.settle_s = settle_s
        self.settle_max_s = settle_max_s
        self.latency = LatencyWindow()
        self._mu = threading.Lock()  # the request flag and the timings below
        self._requested = False
        self._last_burst = -math.inf  # [s, monotonic]
        self._last_plan_at = -math.inf  # end of the last cycle [s, monotonic]
        self._plan_seconds: float | None = None  # EWMA of the planning time [s]
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.busy = threading.Event()  # set while plan_fn runs (tests wait on it)

    @property
    def plan_seconds(self) -> float | None:
        """Smoothed planning time [s] (None before the first plan)."""
        with self._mu:
            return self._plan_seconds

    def request(self, reason: str, burst: bool = False) -> None:
        """Ask for a planning cycle (any thread; never blocks on planning)."""
        self._counters.add(f"replan_requests_{reason}")
        with self._mu:
            self._requested = True
            if burst:
                self._last_burst = self._clock.monotonic()
        self._wake.set()

    def period_due(self) -> bool:
        """Whether ``period_s`` passed since the last cycle (then requests one)."""
        with self._mu:
            due = self._clock.monotonic() - self._last_plan_at >= self.period_s
        if due:
            self.request("period")
        return due

    def step(self) -> bool:
        """One cycle if one was requested; True if a plan was made and applied."""
        with self._mu:
            if not self._requested:
                return False
            self._requested = False
        planned = False
        try:
            work = self._take()
            if work is not None:
                planned = self._plan_and_apply(work)
        finally:
            with self._mu:
                self._last_plan_at = self._clock.monotonic()
        return planned

    def _plan_and_apply(self, work: PlanInput) -> bool:
        began = self._clock.monotonic()
        self.busy.set()
        try:
            plan = self._plan_fn(work.snapshot)
        except Exception:
            self._counters.add("planner_errors")
            _log.exception("planning failed (robots: %d)", len(work.snapshot.robots))
            return False
        finally:
            self.busy.clear()
        took = self._clock.monotonic() - began
        self.latency.add(took)
        with self._mu:
            last = self._plan_seconds
            self._plan_seconds = took if last is None else 0.5 * (last + took)
        self._counters.add("plans")
        self._counters.add("plan_us", round(took * 1e6))  # total planning time [µs]
        _log.debug("planned %d decision(s) in %.3f s", len(plan.decisions), took)
        if plans_log.isEnabledFor(logging.DEBUG):
            line: dict[str, object] = {"at": round(self._clock.wall(), 3)}
            line |= {"took_s": round(took, 6), "robots": len(work.snapshot.robots)}
            line |= plan.summary()
            plans_log.debug("%s", json.dumps(line))
        self._apply(plan, work)
        return True

    # -- own thread ----------------------------------------------------------------------

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="fleet-planner", daemon=True)
            self._thread.start()

    def _settle(self) -> None:
        """Let a burst of submissions settle (bounded by a number of short waits, so a
        clock that does not move cannot hold the worker)."""
        for _ in range(max(1, math.ceil(self.settle_max_s / (self.settle_s / 2)))):
            with self._mu:
                quiet = self._clock.monotonic() - self._last_burst >= self.settle_s
            if quiet or self._stop.wait(self.settle_s / 2):
                return

    def _run(self) -> None:
        while not self._stop.is_set():
            if not self._wake.wait(self.period_s):
                self.request("period")
            if self._stop.is_set():
                return
            self._wake.clear()
            self._settle()
            try:
                self.step()
            except Exception:
                self._counters.add("planner_errors")
                _log.exception("planner cycle failed")

    def close(self) -> None:
        """Stop the thread (a plan under way finishes, and is not applied if the service
        closed meanwhile); idempotent."""
        self._stop.set()
        self._wake.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=10.0)
