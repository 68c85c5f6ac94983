"""The planner's snapshot holds the tasks under way and only the queued tasks a plan may
pair with the available robots (fleet.core.planner.assign.plannable), however many are
queued: its cost follows the robots, not a burst of submissions."""

from __future__ import annotations

from fleet.core.planner import PlanningSnapshot
from fleet.core.tasks import TaskStatus
from tests.fleet.service.conftest import Fleet, ScriptedPlanner, assign_queued, req


def _queued(snapshot: PlanningSnapshot) -> list[str]:
    return [t.task_id for t in snapshot.tasks if t.status is TaskStatus.QUEUED]


def test_a_snapshot_holds_the_oldest_tasks_for_the_available_robots_only() -> None:
    planner = ScriptedPlanner(lambda snapshot: [])
    fleet = Fleet(planner=planner)
    try:
        fleet.join("r1", 0.0, -8.0)
        fleet.join("r2", 3.0, -8.0)
        ids = []
        for k in range(30):  # goals 1.5 m apart, in creation order
            fleet.clock.advance(0.01)
            named = "r2" if k in (5, 6) else None
            ids.append(fleet.service.submit(req(-6.0 + 1.5 * (k % 8), k // 8 * 1.5, named)).id)
        work = fleet.service._take_snapshot()
        assert work is not None
        # two robots: the two oldest unnamed tasks, and r2's oldest task naming it
        assert _queued(work.snapshot) == [ids[0], ids[1], ids[5]]
    finally:
        fleet.service.close()


def test_with_every_robot_busy_no_queued_task_is_copied_to_the_planner() -> None:
    fleet = Fleet(planner=ScriptedPlanner(assign_queued()))
    try:
        fleet.join("r1", 0.0, -8.0)
        first = fleet.service.submit(req(-6.0, 0.0))
        fleet.service.tick()  # planned: r1 takes the first task
        assert fleet.service.task(first.id).status is TaskStatus.ASSIGNED
        for k in range(20):
            fleet.service.submit(req(-6.0 + 1.5 * (k % 8), 1.5 + k // 8 * 1.5))
        work = fleet.service._take_snapshot()
        assert work is not None  # a task under way: worth planning
        assert [t.task_id for t in work.snapshot.tasks] == [first.id]
    finally:
        fleet.service.close()
