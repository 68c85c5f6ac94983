"""The planner on its own worker, with a scripted planner in place of the real one.

Stale plans are rebased or dropped, a plan predicted unsafe never starts a robot, the tick
(resends, timeouts) keeps running while a slow plan is under way, and the worker re-plans
as the yard changes (receding horizon), sending only decisions that change something.
No test here waits on time: only on conditions (``wait_for``) or on a fake clock.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Iterator

import pytest
from support import wait_for

from fleet.core.planner import Plan, PlanningSnapshot, TaskDecision
from fleet.core.tasks import TaskStatus
from fleet.core.types import Law
from fleet.core.wire import ParkAssignment, Pose, RobotMode, RobotState
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.clock import FakeClock
from fleet.service.fleet_service import RATE_WINDOW_S, RESEND_INTERVAL_S, FleetService
from fleet.service.store import MemoryTaskStore
from tests.fleet.service.conftest import ScriptedPlanner, assign_queued, req


class Yard:
    """A service with a scripted planner, a fake clock and robots played by the test."""

    def __init__(self, planner: ScriptedPlanner, background: bool, **settings: object) -> None:
        self.planner = planner
        self.clock = FakeClock()
        self.bus = MemoryBus()
        self.store = MemoryTaskStore()
        self.service = FleetService(
            Settings(**settings),  # type: ignore[arg-type]
            self.bus,
            self.store,
            clock=self.clock,
            planner=planner,
        )
        self.service.start(background=background)
        self.seq = 0

    def state(
        self,
        rid: str,
        x: float,
        mode: RobotMode = RobotMode.IDLE,
        task_id: str | None = None,
        revision: int = 0,
        seq: int | None = None,
    ) -> None:
        self.seq += 1
        self.bus.deliver_state(
            RobotState(
                robot_id=rid,
                seq=self.seq if seq is None else seq,
                stamp=0.0,
                pose=Pose(x=x, y=0.0),
                mode=mode,
                task_id=task_id,
                revision=revision,
            )
        )

    def join(self, rid: str, x: float) -> None:
        self.bus.robot_alive(rid)
        self.state(rid, x)

    def parks(self, rid: str | None = None) -> list[ParkAssignment]:
        return [m for m in self.bus.sent(rid) if isinstance(m, ParkAssignment)]


@pytest.fixture
def yards() -> Iterator[Callable[..., Yard]]:
    made: list[Yard] = []

    def make(planner: ScriptedPlanner, background: bool = False, **settings: object) -> Yard:
        made.append(Yard(planner, background, **settings))
        return made[-1]

    yield make
    for y in made:
        if y.planner.gate is not None:
            y.planner.gate.set()
        y.service.close()


def test_the_tick_keeps_resending_and_timing_out_while_a_slow_plan_runs(
    yards: Callable[..., Yard],
) -> None:
    planner = ScriptedPlanner(assign_queued())
    y = yards(planner, background=True, task_timeout_s=30.0)
    y.join("r1", 0.0)
    y.join("r2", 5.0)
    first = y.service.submit(req(3.0, 0.0, robot="r1"))
    wait_for(lambda: len(y.parks("r1")) == 1, 20, "the first assignment")

    planner.gate = threading.Event()  # from now on the planner blocks until released
    planner.entered.clear()
    second = y.service.submit(req(-3.0, 0.0, robot="r2"))
    assert planner.entered.wait(20), "the planner never started"

    # The planner is stuck; r1 never acknowledged: the tick re-sends, then times out.
    y.clock.advance(RESEND_INTERVAL_S)
    wait_for(lambda: len(y.parks("r1")) >= 2, 20, "a re-send while the planner runs")
    y.clock.advance(31.0)
    wait_for(lambda: y.service.task(first.id).status is TaskStatus.FAILED, 20, "the timeout")
    assert y.service.task(second.id).status is TaskStatus.QUEUED

    planner.gate.set()  # its plan is stale now (the first task failed) but r2's part applies
    wait_for(lambda: y.service.task(second.id).status is TaskStatus.ASSIGNED, 20, "the plan")
    assert y.service.planner_stats().rebased >= 1


def test_a_plan_whose_tasks_all_changed_is_dropped(yards: Callable[..., Yard]) -> None:
    planner = ScriptedPlanner(assign_queued())
    y = yards(planner, background=True)
    y.join("r1", 0.0)
    planner.gate = threading.Event()
    task = y.service.submit(req(3.0, 0.0))
    assert planner.entered.wait(20), "the planner never started"
    y.service.cancel(task.id)  # while the plan that assigns it is being made
    planner.gate.set()
    wait_for(lambda: y.service.planner_stats().stale_dropped == 1, 20, "the stale plan")
    assert y.parks() == []
    stats = y.service.planner_stats()
    assert stats.decisions_stale_dropped == 1 and stats.plans >= 1
    assert stats.p50_ms is not None and stats.p99_ms is not None and stats.window >= 1


def test_a_decision_that_would_start_a_robot_in_an_unsafe_plan_is_never_sent(
    yards: Callable[..., Yard],
) -> None:
    planner = ScriptedPlanner(assign_queued(), safe=False)
    y = yards(planner)
    y.join("r1", 0.0)
    task = y.service.submit(req(3.0, 0.0))
    y.service.tick()
    assert y.parks() == [] and y.service.task(task.id).status is TaskStatus.QUEUED
    assert y.service.counters["plans_unsafe_dropped"] == 1
    assert y.service.planner_stats().unsafe_dropped == 1

    # Held instead (what the planner must do): the task waits, with the reason, and counts
    # as a fallback.
    planner.decide = assign_queued(hold=True, reason="waiting: no safe option")
    y.clock.advance(y.service.settings.replan_period_s)
    y.service.tick()
    (park,) = y.parks()
    assert park.hold
    waiting = y.service.task(task.id)
    assert waiting.status is TaskStatus.WAITING and waiting.reason == "waiting: no safe option"
    assert y.service.planner_stats().fallbacks == 1


def test_a_relaxed_plan_is_counted_and_written_into_the_task_history(
    yards: Callable[..., Yard],
) -> None:
    note = "standstill: no robot could move keeping 0.50 m; planned keeping 0.42 m"
    y = yards(ScriptedPlanner(assign_queued(), notes=(note,)))
    y.join("r1", 0.0)
    assert y.service.planner_stats().relaxed == 0
    task = y.service.submit(req(3.0, 0.0))
    y.service.tick()
    assert y.service.planner_stats().relaxed == 1
    assert y.service.counters["plans_relaxed"] == 1
    assigned = [t for _, event, t in y.store.history(task.id) if event == "assigned"]
    assert [t.reason for t in assigned] == [note]


def test_a_plan_that_is_not_relaxed_leaves_the_reason_empty(yards: Callable[..., Yard]) -> None:
    y = yards(ScriptedPlanner(assign_queued()))
    y.join("r1", 0.0)
    task = y.service.submit(req(3.0, 0.0))
    y.service.tick()
    assigned = [t for _, event, t in y.store.history(task.id) if event == "assigned"]
    assert [t.reason for t in assigned] == [None]
    assert y.service.planner_stats().relaxed == 0


def test_with_the_plans_log_on_every_plan_is_one_json_line_of_what_it_decided(
    yards: Callable[..., Yard], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="fleet.plans")
    y = yards(ScriptedPlanner(assign_queued(predicted_arrival_s=6.0)))
    y.join("r1", 0.0)
    y.join("r2", 5.0)
    y.service.submit(req(3.0, 0.0, robot="r1"))
    y.service.submit(req(-3.0, 0.0, robot="r2"))
    y.service.tick()
    (line,) = [json.loads(r.getMessage()) for r in caplog.records if r.name == "fleet.plans"]
    assert line["at"] == pytest.approx(y.clock.wall()) and line["took_s"] >= 0
    assert line["robots"] == 2 and line["decisions"] == 2 and line["actions"] == {"assign": 2}
    assert line["held"] == 0 and line["short"] == 0 and line["safe"] is True


def test_a_plan_summary_counts_the_robots_it_predicts_short_of_their_goals() -> None:
    decisions = (
        TaskDecision("t1", "r1", "assign", "cw", predicted_arrival_s=9.0),
        TaskDecision("t2", "r2", "keep", "ccw"),  # no arrival within the horizon: short
        TaskDecision("t3", "r3", "assign", "cw", hold=True),  # held: not short
    )
    summary = Plan(4, decisions, True, float("inf"), rollouts=7, clusters=2).summary()
    assert summary["actions"] == {"assign": 2, "keep": 1}
    assert (summary["held"], summary["short"], summary["min_separation_m"]) == (1, 1, None)
    assert json.loads(json.dumps(summary)) == summary


def test_the_worker_replans_as_the_yard_changes_and_resends_only_changes(
    yards: Callable[..., Yard],
) -> None:
    corridor = ((0.0, 0.0, 0.0), (10.0, 5.0, 0.0))  # 0.5 m/s along x
    wanted: dict[str, Law] = {}  # the law the planner wants for tasks under way

    def decide(snapshot: PlanningSnapshot) -> list[TaskDecision]:
        out = assign_queued(corridor=corridor)(snapshot)
        for t in snapshot.tasks:
            if t.robot_id is not None and t.law is not None:
                law = wanted.get("law", t.law)
                action = "keep" if law == t.law else "revise"
                out.append(TaskDecision(t.task_id, t.robot_id, action, law, revision=t.revision))
        return out

    planner = ScriptedPlanner(decide)
    y = yards(planner)
    y.join("r1", 0.0)
    assert len(planner.snapshots) == 0  # nothing to decide: no plan at all
    task = y.service.submit(req(5.0, 0.0))
    y.service.tick()
    assert len(planner.snapshots) == 1 and len(y.parks()) == 1

    # The robot acknowledges at seq 100 (t = 0) and follows its corridor: no re-plan.
    y.state("r1", 0.0, RobotMode.DRIVING, task.id, seq=100)
    y.state("r1", 0.5, RobotMode.DRIVING, task.id, seq=150)  # t = 1 s: predicted 0.5 m
    y.service.tick()
    assert len(planner.snapshots) == 1

    # It falls behind (t = 2 s, predicted 1.0 m, observed 0.5 m): the worker plans again;
    # the plan keeps its law, so nothing is sent.
    y.state("r1", 0.5, RobotMode.DRIVING, task.id, seq=200)
    y.service.tick()
    assert len(planner.snapshots) == 2 and len(y.parks()) == 1
    assert y.service.counters["replan_requests_corridor"] == 1

    # The period brings a plan that flips the law: only then is a revision sent.
    wanted["law"] = "ccw"
    y.clock.advance(y.service.settings.replan_period_s)
    y.service.tick()
    assert len(planner.snapshots) == 3
    assert [(p.revision, p.law) for p in y.parks()] == [(0, "cw"), (1, "ccw")]

    # A robot joining and two robots coming close are triggers too.
    y.join("r2", 3.0)
    y.service.tick()
    assert len(planner.snapshots) == 4
    y.state("r2", 0.8, RobotMode.IDLE)  # 0.3 m from r1 (< 0.5 + 0.2 m), r1 moving
    y.service.tick()
    assert len(planner.snapshots) == 5
    assert y.service.counters["replan_requests_separation"] == 1
    y.service.tick()  # still close: no new trigger
    assert len(planner.snapshots) == 5


@pytest.mark.parametrize("scale", [1, 5])
def test_the_periodic_plan_runs_every_replan_period_of_the_robots_time(
    yards: Callable[..., Yard], scale: int
) -> None:
    """Robots whose states run ``scale`` times faster than the service's clock (a
    time-scaled simulation) are planned for every ``replan_period_s`` of *their* time, as
    real robots would be; robots in real time every ``replan_period_s`` of the service's."""
    planner = ScriptedPlanner(assign_queued())
    y = yards(planner)
    y.join("r1", 0.0)
    task = y.service.submit(req(5.0, 0.0))
    y.service.tick()
    hz, period = y.service.settings.control_rate_hz, y.service.settings.replan_period_s
    step = period / 10  # [s] of the service's clock between states
    seq = y.seq  # its clock runs on from the state it joined with
    before = y.service.counters["replan_requests_period"]
    for _ in range(40):  # 4 periods of the service's clock
        y.clock.advance(step)
        seq += round(step * scale * hz)
        y.state("r1", 0.0, RobotMode.DRIVING, task.id, seq=seq)
        y.service.tick()
    periodic = y.service.counters["replan_requests_period"] - before
    # The rate is measured over its first window (RATE_WINDOW_S, one period here): one
    # plan at the end of it, then every period / scale of the service's clock.
    expected = 1 + round((4 * period - RATE_WINDOW_S) * scale / period)
    assert abs(periodic - expected) <= 1, (periodic, expected)
