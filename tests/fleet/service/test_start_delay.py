"""The planner learns how much of a robot's start delay is left (robot time)."""

from __future__ import annotations

import pytest

from fleet.core.planner import PlanningSnapshot
from fleet.core.wire import RobotMode
from tests.fleet.service.conftest import Fleet, ScriptedPlanner, assign_queued, req


def _seen(snapshot: PlanningSnapshot, task_id: str) -> float | None:
    (task,) = [t for t in snapshot.tasks if t.task_id == task_id]
    return task.start_delay_left_s


def test_the_delay_left_counts_from_the_robots_first_report_of_the_revision() -> None:
    planner = ScriptedPlanner(assign_queued("cw", start_delay_s=6.0))
    fleet = Fleet(planner=planner, task_timeout_s=100.0)
    try:
        period = fleet.settings.replan_period_s
        hz, start = fleet.settings.control_rate_hz, fleet.clock.monotonic()

        def report_waiting() -> None:  # state seq numbers at the control rate: real time
            fleet.seq = round((fleet.clock.monotonic() - start) * hz)
            fleet.robot("r1", 0.0, 0.0, mode=RobotMode.WAITING, task_id=task.id)

        fleet.join("r1", 0.0, 0.0)
        task = fleet.service.submit(req(5.0, 0.0))
        fleet.service.tick()
        assert fleet.parks("r1")[-1].start_delay_s == 6.0

        fleet.clock.advance(period)
        fleet.service.tick()
        assert _seen(planner.snapshots[-1], task.id) is None  # not acknowledged: unknown

        report_waiting()
        fleet.service.tick()
        fleet.clock.advance(period)
        report_waiting()
        fleet.service.tick()
        assert _seen(planner.snapshots[-1], task.id) == pytest.approx(6.0 - period)

        fleet.clock.advance(10.0)
        fleet.service.tick()
        assert _seen(planner.snapshots[-1], task.id) == 0.0  # used up, never negative
    finally:
        fleet.service.close()
