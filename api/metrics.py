"""Prometheus metrics of one app (``GET /metrics``), with a registry of its own.

Two sources, both through the small :class:`MetricsSource` interface (a subset of
:class:`api.deps.FleetAPI`, so the service can grow richer numbers behind it):

* **events** (``add_listener``, on the service's threads, so a task's events may arrive out
  of order: the newest ``updated_at`` wins, and late events of a finished task are ignored):
  task durations (histogram,
  submission -> final state, by final status), tasks finished by status, robots entering
  e-stop, and the smallest separation seen between two robot centres
  (:class:`fleet.core.separation.SeparationTracker`, closer than ``SEPARATION_CUTOFF_M``);
* **a scrape-time read** of the service: active tasks by status (kept from the events,
  seeded from the service at start), robots by mode, the planning latency over the last
  plans (p50, p99: ``planner_stats``), the service's counters -- planning count and time,
  dropped and malformed messages by reason, recoveries, e-stops requested, and every other
  counter as ``parkfleet_service_events_total{event}``.

Names follow Prometheus conventions: ``_total`` counters, ``_seconds`` / ``_meters`` units.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator
from typing import Protocol

from prometheus_client import CollectorRegistry, Counter, Histogram, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from fleet.core.separation import SeparationTracker
from fleet.core.tasks import (
    FleetEvent,
    RobotEvent,
    RobotStatus,
    RobotView,
    Task,
    TaskEvent,
    TaskStatus,
)
from fleet.service.stats import PlannerStats

#: Robots farther apart than this [m] do not move the smallest separation.
SEPARATION_CUTOFF_M = 5.0
#: Finished task ids remembered to ignore their late events.
FINISHED_KEPT = 10_000
#: Buckets of the task duration histogram [s].
DURATION_BUCKETS = (1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1800.0)
_ACTIVE = tuple(s for s in TaskStatus if not s.final)


class MetricsSource(Protocol):
    """What the metrics read from the fleet service."""

    @property
    def counters(self) -> dict[str, int]: ...

    def robots(self) -> list[RobotView]: ...

    def tasks(
        self, status: TaskStatus | None = None, robot_id: str | None = None
    ) -> list[Task]: ...

    def add_listener(self, listener: Callable[[FleetEvent], None]) -> Callable[[], None]: ...

    def planner_stats(self) -> PlannerStats: ...


class FleetMetrics(Collector):
    """The registry of one app and the listener feeding it; :meth:`close` unsubscribes."""

    def __init__(self, source: MetricsSource) -> None:
        self.source = source
        self.registry = CollectorRegistry(auto_describe=True)
        self._lock = threading.Lock()
        self._active: dict[str, tuple[float, TaskStatus]] = {}  # id -> (updated_at, status)
        self._finished: OrderedDict[str, None] = OrderedDict()  # recent final task ids
        self._robot_status: dict[str, RobotStatus] = {}
        self._separation = SeparationTracker(SEPARATION_CUTOFF_M)
        self.durations = Histogram(
            "parkfleet_task_duration_seconds",
            "Time from submission to the final state of a task",
            ["status"],
            buckets=DURATION_BUCKETS,
            registry=self.registry,
        )
        self.finished = Counter(
            "parkfleet_tasks_finished",
            "Tasks that reached a final state, by status",
            ["status"],
            registry=self.registry,
        )
        self.estops = Counter(
            "parkfleet_robot_estops",
            "Times a robot entered the e-stop mode",
            registry=self.registry,
        )
        for status in TaskStatus:
            if status.final:
                self.finished.labels(status.value)
        self.registry.register(self)
        self._unsubscribe = source.add_listener(self.on_event)
        for status in _ACTIVE:  # tasks recovered before we listened
            for task in source.tasks(status=status):
                self._active.setdefault(task.id, (task.updated_at, task.status))

    def close(self) -> None:
        self._unsubscribe()

    def exposition(self) -> bytes:
        """The metrics in the Prometheus text format."""
        return generate_latest(self.registry)

    # -- events (service threads) ---------------------------------------------------------

    def on_event(self, event: FleetEvent) -> None:
        if isinstance(event, TaskEvent):
            task = event.task
            if task.status.final:  # announced once, after it is stored
                with self._lock:
                    self._active.pop(task.id, None)
                    self._finished[task.id] = None
                    while len(self._finished) > FINISHED_KEPT:
                        self._finished.popitem(last=False)
                self.finished.labels(task.status.value).inc()
                self.durations.labels(task.status.value).observe(
                    max(0.0, task.updated_at - task.created_at)
                )
            else:
                with self._lock:
                    known = self._active.get(task.id)
                    if task.id not in self._finished and (
                        known is None or known[0] <= task.updated_at
                    ):
                        self._active[task.id] = (task.updated_at, task.status)
        elif isinstance(event, RobotEvent):
            robot = event.robot
            with self._lock:
                before = self._robot_status.get(robot.robot_id)
                self._robot_status[robot.robot_id] = robot.status
                if robot.status is not RobotStatus.LOST:
                    self._separation.update(robot.robot_id, robot.pose.x, robot.pose.y)
            if robot.status is RobotStatus.ESTOP and before is not RobotStatus.ESTOP:
                self.estops.inc()

    # -- scrape (the Collector protocol) --------------------------------------------------

    def describe(self) -> Iterable[Metric]:
        return []  # unchecked collector: names vary with the service's counters

    def collect(self) -> Iterator[Metric]:
        with self._lock:
            active = [status for _, status in self._active.values()]
            separation = self._separation.minimum
        tasks = GaugeMetricFamily("parkfleet_tasks", "Active tasks by status", labels=["status"])
        for status in _ACTIVE:
            tasks.add_metric([status.value], sum(1 for s in active if s is status))
        yield tasks
        robots = GaugeMetricFamily("parkfleet_robots", "Robots by mode", labels=["mode"])
        views = self.source.robots()
        for mode in RobotStatus:
            robots.add_metric([mode.value], sum(1 for v in views if v.status is mode))
        yield robots
        yield GaugeMetricFamily(
            "parkfleet_min_separation_meters",
            f"Smallest centre distance seen between two robots (+Inf: none within "
            f"{SEPARATION_CUTOFF_M:g} m)",
            value=separation if math.isfinite(separation) else math.inf,
        )
        stats = self.source.planner_stats()
        latency = GaugeMetricFamily(
            "parkfleet_planning_latency_seconds",
            f"Planning time over the last {stats.window} plans, by quantile",
            labels=["quantile"],
        )
        for quantile, ms in (("0.5", stats.p50_ms), ("0.99", stats.p99_ms)):
            latency.add_metric([quantile], math.nan if ms is None else ms / 1e3)
        yield latency
        yield from self._counters(dict(self.source.counters))

    def _counters(self, counters: dict[str, int]) -> Iterator[Metric]:
        plans = CounterMetricFamily("parkfleet_plans", "Planning runs")
        plans.add_metric([], counters.pop("plans", 0))
        yield plans
        planning = CounterMetricFamily(
            "parkfleet_planning_seconds", "Wall time spent planning (divide by plans: mean)"
        )
        planning.add_metric([], counters.pop("plan_us", 0) / 1e6)
        yield planning
        dropped = CounterMetricFamily(
            "parkfleet_messages_dropped",
            "Malformed, oversized or misaddressed messages dropped, by reason",
            labels=["reason"],
        )
        for key in sorted(k for k in counters if k.startswith("bus_dropped_")):
            dropped.add_metric([key.removeprefix("bus_dropped_")], counters.pop(key))
        if "bus_state_key_mismatch" in counters:
            dropped.add_metric(["key_mismatch"], counters.pop("bus_state_key_mismatch"))
        yield dropped
        for name, key, text in (
            ("parkfleet_recoveries", "recoveries", "Recovery attempts of stuck robots"),
            ("parkfleet_estops_requested", "estops_requested", "E-stops requested via the API"),
        ):
            family = CounterMetricFamily(name, text)
            family.add_metric([], counters.pop(key, 0))
            yield family
        other = CounterMetricFamily(
            "parkfleet_service_events", "Other counters of the fleet service", labels=["event"]
        )
        for key in sorted(counters):
            other.add_metric([key], counters[key])
        yield other
