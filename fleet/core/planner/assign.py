"""Which available robot takes which queued task (pure; :mod:`fleet.core.assignment`).

Queued tasks that name a robot go to it, first come first served, when it is available;
the others go to the remaining available robots by the optimal assignment on predicted
solo arrival times (Hungarian method; only each task's nearest robots and each robot's
nearest tasks are priced by rollout, ``PlannerConfig.assignment_candidates``).
"""

from __future__ import annotations

from fleet.core.assignment import TaskSpec, optimal_assignment, predicted_times
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.model import PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.tasks import TaskStatus
from fleet.core.types import LAWS


def pair_queued(
    snapshot: PlanningSnapshot, config: PlannerConfig
) -> list[tuple[TaskSnapshot, RobotSnapshot]]:
    """(task, robot) pairs for the queued tasks of ``snapshot`` (oldest tasks first)."""
    queued = sorted(
        (t for t in snapshot.tasks if t.status == TaskStatus.QUEUED), key=lambda t: t.created_at
    )
    available = {r.robot_id: r for r in snapshot.robots if r.available}
    pairs: list[tuple[TaskSnapshot, RobotSnapshot]] = []
    for task in queued:
        rid = task.named_robot
        if rid is not None and rid in available:
            pairs.append((task, available.pop(rid)))
    unnamed = [t for t in queued if t.named_robot is None][: len(available)]
    if unnamed and available:
        robots = list(available.values())
        specs = [
            TaskSpec(
                goal=t.goal,
                laws=LAWS if t.direction == "auto" else (t.direction,),
                gains=t.gains,
                tolerance=t.tolerance,
            )
            for t in unnamed
        ]
        cost = predicted_times(
            [r.pose for r in robots],
            specs,
            snapshot.profile,
            snapshot.obstacles,
            snapshot.avoidance,
            nearest=config.assignment_candidates,
        )
        for i, j in optimal_assignment(cost):
            pairs.append((unnamed[j], robots[i]))
    return pairs


__all__ = ["pair_queued"]
