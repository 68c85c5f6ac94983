"""The outbox: applies the effects of the service's transitions outside its lock, in order.

The service queues each transition's effects (:mod:`fleet.service.effects`) as one batch
**while it still holds its lock**, so batches are queued in the order the transitions
happened, and :class:`Outbox` applies them **after the lock is released**, batch after batch
in that order, and inside a batch: every store write first, then the publishes, then the
notifications -- stored before announced. A batch whose store write fails is not announced
(counted ``store_errors``).

The outbox either has its own thread (``start``; the service's normal mode: bus callbacks,
the tick and the planner only queue) or is drained by the caller (:meth:`Outbox.run_pending`;
the service's single-threaded test mode). :meth:`Outbox.wait` blocks until a batch is
applied (the API's cancel answers only once the cancel is stored). A listener may call back
into the service: effects queued from inside a listener are applied by the drain already
running, after the current batch.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable

from fleet.core.tasks import FleetEvent
from fleet.core.wire import ControlCommand, ObstacleSet
from fleet.service.bus import FleetBus
from fleet.service.effects import Effects, Notify, Publish, PurgeFinished, SaveState, StoreWrite
from fleet.service.stats import Counters
from fleet.service.store import TaskStore

_log = logging.getLogger(__name__)

Listener = Callable[[FleetEvent], None]


class Batch:
    """The effects of one transition (or of one locked section), applied together."""

    __slots__ = ("done", "effects", "error")

    def __init__(self, effects: Effects) -> None:
        self.effects = effects
        self.done = False
        self.error: BaseException | None = None


class Outbox:
    """Applies queued effect batches in order, never under the service lock."""

    def __init__(
        self,
        store: TaskStore,
        bus: FleetBus,
        counters: Counters,
        lock_held: Callable[[], bool],
    ) -> None:
        self._store = store
        self._bus = bus
        self._counters = counters
        self._lock_held = lock_held
        self._listeners: tuple[Listener, ...] = ()
        self._listeners_lock = threading.Lock()
        self._cv = threading.Condition()  # the queue
        self._queue: deque[Batch] = deque()
        self._drain_lock = threading.Lock()
        self._drainer: int | None = None  # thread id of the drain under way
        self._thread: threading.Thread | None = None
        self._stopping = False

    # -- listeners ---------------------------------------------------------------------

    def add_listener(self, listener: Listener) -> Callable[[], None]:
        with self._listeners_lock:
            self._listeners = (*self._listeners, listener)

        def unsubscribe() -> None:
            with self._listeners_lock:
                listeners = list(self._listeners)
                if listener in listeners:
                    listeners.remove(listener)
                self._listeners = tuple(listeners)

        return unsubscribe

    def emit(self, events: list[FleetEvent]) -> None:
        """Call every listener with each event, on this thread (errors counted, logged)."""
        listeners = self._listeners
        for event in events:
            for listener in listeners:
                try:
                    listener(event)
                except Exception:
                    self._counters.add("listener_errors")
                    _log.exception("fleet event listener failed")

    # -- queueing and applying ---------------------------------------------------------

    def enqueue(self, effects: Effects) -> Batch | None:
        """Queue a batch (call while holding the service lock, to keep the order)."""
        if not effects:
            return None
        batch = Batch(effects)
        with self._cv:
            self._queue.append(batch)
            self._cv.notify_all()
        return batch

    @property
    def pending(self) -> int:
        with self._cv:
            return len(self._queue)

    def run_pending(self) -> None:
        """Apply every queued batch on this thread (a no-op inside a listener: the drain
        that called it applies the rest)."""
        me = threading.get_ident()
        if self._drainer == me:
            return
        with self._drain_lock:
            self._drainer = me
            try:
                while True:
                    with self._cv:
                        if not self._queue:
                            return
                        batch = self._queue.popleft()
                    self._apply(batch)
            finally:
                self._drainer = None

    def wait(self, batch: Batch | None) -> None:
        """Until ``batch`` is applied (drained here when no thread runs); re-raises its
        store error."""
        if batch is None or self._drainer == threading.get_ident():
            return
        if self._thread is None:
            self.run_pending()
        with self._cv:
            while not batch.done:
                self._cv.wait()
        if batch.error is not None:
            raise batch.error

    def _apply(self, batch: Batch) -> None:
        if self._lock_held():  # the rule this module exists for
            raise AssertionError("effects applied while holding the service lock")
        try:
            self._apply_effects(batch)
        except BaseException as exc:  # a broken store or bus must not stop the runner
            batch.error = exc
        finally:
            with self._cv:
                batch.done = True
                self._cv.notify_all()

    def _apply_effects(self, batch: Batch) -> None:
        effects = batch.effects
        try:
            for e in effects:
                if isinstance(e, StoreWrite):
                    self._store.save(e.task, e.event)
                elif isinstance(e, SaveState):
                    self._store.save_state(e.key, e.value)
                elif isinstance(e, PurgeFinished):
                    purged = self._store.delete_finished_before(e.before, e.limit)
                    self._counters.add("tasks_purged", purged)
        except Exception:
            self._counters.add("store_errors")
            _log.exception("task store write failed: its publishes and events are dropped")
            raise
        for e in effects:
            if isinstance(e, Publish):
                try:
                    msg = e.message
                    if isinstance(msg, ObstacleSet):
                        self._bus.publish_obstacles(msg)
                    elif isinstance(msg, ControlCommand):
                        self._bus.publish_control(msg)
                    else:
                        self._bus.publish_assignment(msg)
                except Exception:
                    self._counters.add("publish_errors")
                    _log.exception("publish failed")
        self.emit([e.event for e in effects if isinstance(e, Notify)])

    # -- own thread ----------------------------------------------------------------------

    def start(self) -> None:
        """Apply batches on a thread of its own from now on."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="fleet-effects", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._queue and not self._stopping:
                    self._cv.wait()
                if not self._queue and self._stopping:
                    return
            self.run_pending()

    def close(self) -> None:
        """Apply what is queued, then stop the thread; idempotent."""
        with self._cv:
            self._stopping = True
            self._cv.notify_all()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=30.0)
        self.run_pending()
