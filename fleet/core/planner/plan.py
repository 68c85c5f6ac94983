"""``plan``: who takes which task, with which law, and when (pure; snapshot in, plan out).

This first planner keeps the service's original rules (it moved here from the service):

1. **Assignment.** Queued tasks that name a robot go to it first come, first served when it
   is available; the others go to available robots by the optimal assignment on predicted
   solo arrival times (:mod:`fleet.core.assignment`); a task taken from a stuck robot
   (``TaskSnapshot.avoid_robot``) goes back to that robot only if no other one can take it.
2. **Direction.** ``auto`` tasks get cw or ccw from closed-loop rollouts of the whole
   fleet (:func:`fleet.core.direction.choose_directions`): robots under way keep their law
   unless flipping some of them is strictly safer; standing robots (idle, arrived,
   holding, waiting, lost) are obstacles where they stand.
3. **Never unsafe.** When the chosen laws are still predicted to bring a pair of robots
   closer than ``separation_m``, the new robots do not start: they are assigned with
   ``hold`` and the reason (their tasks wait), and are planned again later.
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.core.assignment import TaskSpec, optimal_assignment, predicted_times
from fleet.core.direction import Mover, Scene, choose_directions
from fleet.core.planner.model import (
    Plan,
    PlanningSnapshot,
    RobotSnapshot,
    TaskDecision,
    TaskSnapshot,
)
from fleet.core.tasks import TaskStatus
from fleet.core.types import LAWS, Law

#: Task statuses of a task under way (it has a robot).
UNDER_WAY = (TaskStatus.ASSIGNED, TaskStatus.DRIVING, TaskStatus.WAITING)
#: Added to the predicted time [s] of giving a task back to the robot it avoids.
AVOID_COST_S = 1e6


@dataclass(frozen=True)
class PlannerConfig:
    """Search bounds of the planner (see :func:`fleet.core.direction.choose_directions`)."""

    exhaustive_limit: int = 4
    budget: int = 24


def _pairs(
    snapshot: PlanningSnapshot, queued: list[TaskSnapshot]
) -> list[tuple[TaskSnapshot, RobotSnapshot]]:
    """Queued tasks matched to available robots (named first come, first served)."""
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
        )
        index = {r.robot_id: i for i, r in enumerate(robots)}
        for j, t in enumerate(unnamed):
            i = index.get(t.avoid_robot or "")
            if i is not None:
                cost[i, j] += AVOID_COST_S
        for i, j in optimal_assignment(cost):
            pairs.append((unnamed[j], robots[i]))
    return pairs


def plan(snapshot: PlanningSnapshot, config: PlannerConfig | None = None) -> Plan:
    """Decide the queued and under-way tasks of ``snapshot`` (see the module docstring)."""
    config = config or PlannerConfig()
    robots = {r.robot_id: r for r in snapshot.robots}
    queued = sorted(
        (t for t in snapshot.tasks if t.status == TaskStatus.QUEUED), key=lambda t: t.created_at
    )
    under_way = [
        t
        for t in snapshot.tasks
        if t.status in UNDER_WAY and t.robot_id in robots and t.law is not None and not t.hold
    ]
    pairs = _pairs(snapshot, queued)
    if not pairs:
        return Plan(snapshot.version, (), True, float("inf"))

    movers: list[Mover] = []
    moving: set[str] = set()
    for t in under_way:
        assert t.robot_id is not None and t.law is not None
        movers.append(
            Mover(
                robot_id=t.robot_id,
                pose=robots[t.robot_id].pose,
                goal=t.goal,
                gains=t.gains,
                tolerance=t.tolerance,
                law=t.law,
                auto=t.direction == "auto",
            )
        )
        moving.add(t.robot_id)
    for task, robot in pairs:
        fixed: Law | None = None if task.direction == "auto" else task.direction
        movers.append(
            Mover(
                robot_id=robot.robot_id,
                pose=robot.pose,
                goal=task.goal,
                gains=task.gains,
                tolerance=task.tolerance,
                law=fixed,
                auto=fixed is None,
            )
        )
        moving.add(robot.robot_id)
    standing = [r.pose[:2] for r in snapshot.robots if r.robot_id not in moving]
    scene = Scene(
        movers=movers,
        standing=[(x, y) for x, y in standing],
        obstacles=snapshot.obstacles,
        avoidance=snapshot.avoidance,
        profile=snapshot.profile,
        lead_time=snapshot.lead_time_s,
    )
    choice = choose_directions(
        scene,
        snapshot.separation_m,
        dt=snapshot.control_dt,
        exhaustive_limit=config.exhaustive_limit,
        budget=config.budget,
    )
    best = choice.best
    laws = best.laws
    decisions: list[TaskDecision] = []
    for k, t in enumerate(under_way):
        assert t.robot_id is not None and t.law is not None
        if laws[k] != t.law:
            decisions.append(
                TaskDecision(t.task_id, t.robot_id, "revise", laws[k], revision=t.revision)
            )
    first_new = len(under_way)
    hold_reason = None
    if not best.safe:
        hold_reason = (
            f"waiting: every option was predicted to bring robots within "
            f"{best.min_separation:.2f} m of each other (< {snapshot.separation_m:g} m)"
        )
    for k, (task, robot) in enumerate(pairs):
        decisions.append(
            TaskDecision(
                task.task_id,
                robot.robot_id,
                "assign",
                laws[first_new + k],
                revision=task.revision,
                hold=hold_reason is not None,
                reason=hold_reason,
            )
        )
    return Plan(
        snapshot_version=snapshot.version,
        decisions=tuple(decisions),
        safe=best.safe,
        min_separation_m=best.min_separation,
        rollouts=choice.evaluations,
        clusters=1,
        waiting=len(pairs) if hold_reason else 0,
        notes=tuple(choice.searched),
    )


__all__ = ["UNDER_WAY", "PlannerConfig", "plan"]
