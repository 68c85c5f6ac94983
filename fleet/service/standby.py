"""A fleet service that leads or stands by on PostgreSQL (docs/deployment.md "Standby and fencing").

:class:`FailoverService` is what the API talks to when the store is PostgreSQL. It runs a
:class:`~fleet.service.leadership.Leadership` and

* **as a standby** serves reads from the shared store (tasks, their history) and follows it:
  a ``LISTEN parkfleet_tasks`` thread turns every committed change into a ``TaskEvent`` for
  the listeners (``/events``); writes raise :class:`NotLeader` with the leader's address (the
  API answers 503 and names it). Robots, paths and plans are the leader's: a standby lists
  none.
* **on taking over** builds a fresh :class:`~fleet.service.fleet_service.FleetService`: its
  ``start`` rebuilds the ledger from the store (unfinished tasks keep their robot and law,
  assignments are re-sent until acknowledged) and the planner plans from the robots' live
  states as they arrive on the bus; robots drive on meanwhile (their control loop is their
  own).
* **on stepping down** closes that service: it stops commanding at once.

Every message the leader publishes goes through :class:`FencedBus`, which stamps the
fencing term on assignments, cancels and the service's control commands and drops them
(counted) once this process is no longer the leader of that term.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from typing import Any

import psycopg
import zenoh

from fleet.core.planner import plan
from fleet.core.tasks import (
    FleetEvent,
    RobotNotFound,
    RobotView,
    Task,
    TaskEvent,
    TaskNotFound,
    TaskRequest,
    TaskStatus,
)
from fleet.core.wire import (
    CancelAssignment,
    ControlAction,
    ControlCommand,
    Hold,
    Keys,
    Obstacle,
    ObstacleSet,
    ParkAssignment,
    Pose,
)
from fleet.io.heap import HeapTrimmer
from fleet.io.settings import Settings
from fleet.io.transport import listening_locators, open_session
from fleet.service.bays import BayState
from fleet.service.bus import FleetBus, FleetSink
from fleet.service.control_desk import ControlState
from fleet.service.fleet_service import FleetService
from fleet.service.leadership import LeaderRecord, Leadership, read_leader
from fleet.service.planner_process import PlannerProcess
from fleet.service.planner_worker import PlanFunction
from fleet.service.roles import FailoverStatus, NotLeader, Role
from fleet.service.stats import PlannerStats
from fleet.service.store_postgres import TASKS_CHANNEL, PostgresTaskStore, connect
from fleet.service.zenoh_bus import ZenohFleetBus
from fleet.service.zones import ZoneState

_log = logging.getLogger(__name__)


class FencedBus:
    """A :class:`~fleet.service.bus.FleetBus` that stamps ``term`` on what it publishes and
    publishes only while ``leading()`` (else drops and counts, ``fenced_drops``)."""

    def __init__(self, bus: FleetBus, term: int, leading: Callable[[], bool]) -> None:
        self._bus = bus
        self.term = term
        self._leading = leading
        self.fenced_drops = 0

    def start(self, sink: FleetSink) -> None:
        self._bus.start(sink)

    def publish_assignment(self, msg: ParkAssignment | CancelAssignment) -> None:
        if self._leading():
            self._bus.publish_assignment(msg.model_copy(update={"term": self.term}))
        else:
            self.fenced_drops += 1

    def publish_obstacles(self, msg: ObstacleSet) -> None:
        if self._leading():
            self._bus.publish_obstacles(msg)

    def publish_control(self, msg: ControlCommand) -> None:
        if self._leading():
            self._bus.publish_control(msg.model_copy(update={"term": self.term}))
        else:
            self.fenced_drops += 1

    @property
    def counters(self) -> dict[str, int]:
        return {**self._bus.counters, "fenced_drops": self.fenced_drops}

    def close(self) -> None:
        self._bus.close()


class FailoverService:
    """Leader or standby on one PostgreSQL store (module docstring); implements what the API
    needs of a fleet service (``api.deps.FleetAPI``)."""

    def __init__(
        self,
        settings: Settings,
        store: PostgresTaskStore,
        make_bus: Callable[[], FleetBus],
        *,
        name: str,
        address: str,
        planner: PlanFunction | None = None,
    ) -> None:
        self.settings = settings
        self.store = store
        #: How every term's service plans (None: the planner on its worker thread); a
        #: :class:`~fleet.service.planner_process.PlannerProcess` outlives the terms.
        self._plan = planner
        self.name = name
        self.address = address
        self._make_bus = make_bus
        self._lock = threading.Lock()  # self._leader only; never held across I/O
        self._leader: FleetService | None = None
        self._listeners: list[Callable[[FleetEvent], None]] = []
        self._unsubscribe: list[Callable[[], None]] = []
        self.takeovers = 0
        self.followed = 0  # store changes seen by the follower
        self.leadership = Leadership(
            store,
            name,
            address,
            lease_s=settings.leader_lease_s,
            poll_s=settings.leader_poll_s,
            on_elected=self._take_over,
            on_deposed=self._step_down,
        )
        self._stop = threading.Event()
        self._follower: threading.Thread | None = None
        self._listen: psycopg.Connection[Any] | None = None

    # -- life ---------------------------------------------------------------------------
    def start(self) -> FailoverService:
        self._follower = threading.Thread(target=self._follow, name="fleet-follow", daemon=True)
        self._follower.start()
        self.leadership.start()
        return self

    def close(self) -> None:
        self._stop.set()
        self.leadership.close()  # steps down: closes the leading service
        listen = self._listen
        if listen is not None:
            listen.close()  # wakes the follower
        if self._follower is not None:
            self._follower.join(timeout=10.0)

    def _take_over(self, term: int) -> None:
        """Elected (on the leadership thread): a fresh service, ledger from the store."""
        bus = FencedBus(
            self._make_bus(),
            term,
            lambda: self.leadership.role is Role.LEADER and self.leadership.term == term,
        )
        service = FleetService(self.settings, bus, self.store, planner=self._plan)
        with self._lock:
            listeners = list(self._listeners)
        self._unsubscribe = [service.add_listener(fn) for fn in listeners]
        service.start()
        self.takeovers += 1
        with self._lock:
            self._leader = service  # from now on failover_status says leader
        _log.info("%s leads (term %d): %d tasks recovered", self.name, term,
                  service.counters.get("tasks_recovered", 0))  # fmt: skip

    def _step_down(self, reason: str) -> None:
        with self._lock:
            service, self._leader = self._leader, None
        if service is not None:
            service.close()
        for undo in self._unsubscribe:
            undo()
        self._unsubscribe = []

    def _follow(self) -> None:
        """LISTEN to the store's changes; as a standby, hand each to the listeners."""
        while not self._stop.is_set():
            try:
                self._listen = connect(self.store.dsn, timeout_s=self.settings.leader_lease_s)
                self._listen.execute(f"LISTEN {TASKS_CHANNEL}")
                for note in self._listen.notifies():
                    if self._stop.is_set():
                        break
                    self.followed += 1
                    if self.leading is None:
                        self._announce(note.payload)
            except (psycopg.Error, ConnectionError) as exc:
                if not self._stop.is_set():
                    _log.warning("following the store failed (%s): retrying", exc)
                    self._stop.wait(self.settings.leader_poll_s * 10)
            finally:
                if self._listen is not None:
                    self._listen.close()

    def _announce(self, task_id: str) -> None:
        task = self.store.get(task_id)
        if task is None:
            return
        with self._lock:
            listeners = list(self._listeners)
        for fn in listeners:
            fn(TaskEvent(task=task))

    # -- who leads ----------------------------------------------------------------------
    @property
    def leading(self) -> FleetService | None:
        with self._lock:
            return self._leader

    def failover_status(self) -> FailoverStatus:
        """Role and term as last seen (no database round trip: ``/healthz`` is async). A
        process elected but still building its service (the ledger from the store) says
        standby until the service leads: a leader then serves writes and its counters."""
        lead = self.leadership
        if lead.role is Role.LEADER and self.leading is not None:
            return FailoverStatus(Role.LEADER, lead.term, self.address, self.name)
        return FailoverStatus(Role.STANDBY, lead.seen_term, lead.seen_leader, self.name)

    def leader_record(self) -> LeaderRecord:
        return read_leader(self.store)

    def _writer(self) -> FleetService:
        service = self.leading
        if service is None:
            raise NotLeader(self.leadership.seen_leader)
        return service

    # -- the API's FleetAPI -------------------------------------------------------------
    @property
    def counters(self) -> dict[str, int]:
        service = self.leading
        own = {
            "takeovers": self.takeovers,
            "store_changes_followed": self.followed,
            "step_downs": self.leadership.step_downs,
        }
        return own if service is None else {**service.counters, **own}

    def submit(self, request: TaskRequest, idempotency_key: str | None = None) -> Task:
        return self._writer().submit(request, idempotency_key)

    def cancel(self, task_id: str) -> Task:
        return self._writer().cancel(task_id)

    def task(self, task_id: str) -> Task:
        service = self.leading
        if service is not None:
            return service.task(task_id)
        task = self.store.get(task_id)
        if task is None:
            raise TaskNotFound(f"no task {task_id}")
        return task

    def history(self, task_id: str) -> list[tuple[float, str, Task]]:
        service = self.leading
        if service is not None:
            return service.history(task_id)
        rows = self.store.history(task_id)
        if not rows:
            raise TaskNotFound(f"no task {task_id}")
        return rows

    def tasks(self, status: TaskStatus | None = None, robot_id: str | None = None) -> list[Task]:
        return self.store.list(status=status, robot_id=robot_id)

    def submit_to_bay(
        self,
        bay: str | None,
        group: str | None,
        make: Callable[[Pose, str], TaskRequest],
        idempotency_key: str | None = None,
    ) -> Task:
        return self._writer().submit_to_bay(bay, group, make, idempotency_key)

    def bays(self) -> list[BayState]:
        service = self.leading
        return [] if service is None else service.bays()

    def zones(self) -> list[ZoneState]:
        service = self.leading
        return [] if service is None else service.zones()

    def decommission(self, robot_id: str) -> RobotView:
        return self._writer().decommission(robot_id)

    def commission(self, robot_id: str) -> RobotView:
        return self._writer().commission(robot_id)

    def robots(self) -> list[RobotView]:
        service = self.leading
        return [] if service is None else service.robots()

    def robot(self, robot_id: str) -> RobotView:
        service = self.leading
        if service is None:
            raise RobotNotFound(f"no robot {robot_id} (this service is a standby)")
        return service.robot(robot_id)

    def remove_robot(self, robot_id: str) -> None:
        self._writer().remove_robot(robot_id)

    def obstacles(self) -> list[Obstacle]:
        service = self.leading
        site = self.settings.site
        if service is None:
            return [] if site is None else site.static_obstacles()
        return service.obstacles()

    def set_obstacles(self, obstacles: list[Obstacle]) -> None:
        self._writer().set_obstacles(obstacles)

    def path(self, task_id: str) -> list[tuple[float, float, float, float, float, float]]:
        service = self.leading
        if service is None:
            self.task(task_id)  # 404 for an unknown task
            return []
        return service.path(task_id)

    def add_listener(self, listener: Callable[[FleetEvent], None]) -> Callable[[], None]:
        with self._lock:
            self._listeners.append(listener)
            service = self._leader
        undo_leader = service.add_listener(listener) if service is not None else None

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)
            if undo_leader is not None:
                undo_leader()

        return unsubscribe

    def control(
        self, action: ControlAction, robot_id: str | None = None, reason: str | None = None
    ) -> ControlCommand:
        return self._writer().control(action, robot_id, reason)

    def control_state(self) -> ControlState:
        service = self.leading
        return ControlState(Hold(), {}) if service is None else service.control_state()

    def planner_stats(self) -> PlannerStats:
        service = self.leading
        if service is None:
            return PlannerStats(0, 0, None, None, 0, 0, 0, 0, 0)
        return service.planner_stats()

    def sizes(self) -> dict[str, int]:
        service = self.leading
        return {} if service is None else service.sizes()


@dataclass(frozen=True)
class RunningFailover:
    """A leader-or-standby opened by :func:`open_failover`, open until the ``with`` ends."""

    session: zenoh.Session
    store: PostgresTaskStore
    service: FailoverService
    locators: list[str]


@contextmanager
def open_failover(settings: Settings) -> Iterator[RunningFailover]:
    """Like :func:`fleet.service.host.open_fleet` for a PostgreSQL ``settings.store``: the
    planner's own process (``settings.planner_process``, spawned first), the router
    session, the store, the :class:`FailoverService` (a Zenoh bus per term it leads)
    and the heap trimmer; closed in reverse. The service is named ``<host>:<pid>``; it gives
    ``settings.advertise_url`` (else its API address) as its address when it leads."""
    if settings.store is None:
        raise ValueError("open_failover needs a postgresql:// store")
    with ExitStack() as stack:
        planner: PlannerProcess | None = None
        if settings.planner_process:
            planner = PlannerProcess(plan)
            stack.callback(planner.close)  # after the last term's service stopped
        session = open_session(settings, "router")
        stack.callback(session.close)
        locators = listening_locators(session)
        store = PostgresTaskStore(settings.store)
        stack.callback(store.close)
        keys = Keys(settings.fleet_name)
        service = FailoverService(
            settings,
            store,
            lambda: ZenohFleetBus(session, keys),
            name=f"{socket.gethostname()}:{os.getpid()}",
            address=settings.advertise_url or f"http://{settings.api_host}:{settings.api_port}",
            planner=planner,
        )
        stack.callback(service.close)
        service.start()
        trimmer = HeapTrimmer(settings.heap_trim_interval_s)
        stack.callback(trimmer.close)
        trimmer.start()
        yield RunningFailover(session, store, service, locators)
