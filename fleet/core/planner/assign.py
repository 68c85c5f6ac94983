"""Which available robot takes which queued task (pure; :mod:`fleet.core.assignment`).

Queued tasks that name a robot go to it, first come first served, when it is available;
the others go to the remaining available robots by the optimal assignment on predicted
solo arrival times (Hungarian method; only each task's nearest robots and each robot's
nearest tasks are priced by rollout, ``PlannerConfig.assignment_candidates``). A pair whose
straight run passes within ``separation + STUCK_MARGIN_M`` of a robot that stays there (or
of the goal of a task under way: a robot will park there) costs ``BLOCKED_S`` more, so
another robot takes the task when one can: the blocked one could wait for ever. The planner
also passes the pairs whose solo paths turned out blocked (``avoid``), and a task taken
from a stuck robot (``TaskSnapshot.avoid_robot``) avoids that robot the same way.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable
from typing import TypeVar

import numpy as np

from fleet.core.assignment import TaskSpec, optimal_assignment, predicted_times
from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.model import PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.planner.scene import STUCK_MARGIN_M, UNDER_WAY_STATUSES
from fleet.core.tasks import TaskStatus
from fleet.core.types import LAWS, BoolArray

#: [s] added to the predicted time of a blocked pair (see the module docstring).
BLOCKED_S = 300.0

_Queued = TypeVar("_Queued")


def plannable(
    queued: Iterable[_Queued], available: Collection[str], named: Callable[[_Queued], str | None]
) -> list[_Queued]:
    """The queued tasks a plan may pair with robots, from ``queued`` oldest first (in that
    order): for each robot in ``available`` the oldest task that names it, and the
    ``len(available)`` oldest that name none (``named``: the robot a task names, or None).
    :func:`pair_queued` pairs no other task, so a snapshot without the others plans the
    same (the fleet service leaves them out: thousands queued by a burst cost more to copy
    to the planner than the plan)."""
    free = set(available)
    unnamed = len(free)
    out: list[_Queued] = []
    for task in queued:
        if not free and not unnamed:
            break
        rid = named(task)
        if rid is None:
            if unnamed:
                out.append(task)
                unnamed -= 1
        elif rid in free:
            free.remove(rid)
            out.append(task)
    return out


def _blocked(
    snapshot: PlanningSnapshot, robots: list[RobotSnapshot], tasks: list[TaskSnapshot]
) -> BoolArray:
    """(R, T) whether robot r's straight run to task t's goal passes a blocker: a robot
    that stays (not available, no task under way: lost, holding) or the goal of a task
    under way. Available robots may be about to leave: the planner checks those after
    pairing, on the solo paths (:func:`fleet.core.planner.scene.stuck`)."""
    busy = {t.robot_id for t in snapshot.tasks if t.status in UNDER_WAY_STATUSES}
    still = [
        (r.robot_id, r.pose[:2])
        for r in snapshot.robots
        if r.robot_id not in busy and not r.available
    ]
    parked = [t.goal[:2] for t in snapshot.tasks if t.status in UNDER_WAY_STATUSES]
    points = np.array([p for _, p in still] + parked, dtype=np.float64).reshape(-1, 2)
    owner = [rid for rid, _ in still] + [None] * len(parked)
    a = np.array([r.pose[:2] for r in robots], dtype=np.float64)[:, None, None, :]
    b = np.array([t.goal[:2] for t in tasks], dtype=np.float64)[None, :, None, :]
    p = points[None, None, :, :]
    ab = b - a
    s = np.clip(((p - a) * ab).sum(axis=3) / np.maximum((ab * ab).sum(axis=3), 1e-12), 0, 1)
    d = np.hypot(*np.moveaxis(a + s[..., None] * ab - p, 3, 0))  # (R, T, P)
    mine = np.array([[o == r.robot_id for o in owner] for r in robots], dtype=bool)
    mine = mine.reshape(len(robots), 1, -1)
    reach = snapshot.separation_m + STUCK_MARGIN_M
    out: BoolArray = ((d < reach) & ~mine).any(axis=2)
    return out


def pair_queued(
    snapshot: PlanningSnapshot,
    config: PlannerConfig,
    avoid: frozenset[tuple[str, str]] = frozenset(),
) -> list[tuple[TaskSnapshot, RobotSnapshot]]:
    """(task, robot) pairs for the queued tasks of ``snapshot`` (oldest tasks first);
    unnamed tasks avoid the (task id, robot id) pairs in ``avoid`` if they can."""
    available = {r.robot_id: r for r in snapshot.robots if r.available}
    queued = plannable(
        sorted(
            (t for t in snapshot.tasks if t.status == TaskStatus.QUEUED),
            key=lambda t: t.created_at,
        ),
        available,
        lambda t: t.named_robot,
    )
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
            [r.profile or snapshot.profile for r in robots],
            snapshot.obstacles,
            snapshot.avoidance,
            nearest=config.assignment_candidates,
        )
        blocked = _blocked(snapshot, robots, unnamed)
        for i, r in enumerate(robots):
            for j, t in enumerate(unnamed):
                blocked[i, j] |= (t.task_id, r.robot_id) in avoid or t.avoid_robot == r.robot_id
        cost = cost + BLOCKED_S * blocked
        for i, j in optimal_assignment(cost):
            pairs.append((unnamed[j], robots[i]))
    return pairs


__all__ = ["pair_queued", "plannable"]
