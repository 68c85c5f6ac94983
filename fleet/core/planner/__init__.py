"""The fleet planner: snapshot in, plan out (pure; run by the service on its own thread).

- :mod:`~fleet.core.planner.model`: the snapshot it reads and the decisions it makes (the
  contract with the service).
- :mod:`~fleet.core.planner.plan`: :func:`plan`, the steps below in order.
- :mod:`~fleet.core.planner.assign`: queued tasks to available robots.
- :mod:`~fleet.core.planner.scene`: movers, standing robots, lead-in, solo predictions.
- :mod:`~fleet.core.planner.gates`: single-robot zones -- who goes through first, who waits.
- :mod:`~fleet.core.planner.clusters`: robots whose predicted paths interact.
- :mod:`~fleet.core.planner.search`: law, start delay or hold per robot of a cluster.
- :mod:`~fleet.core.planner.cost`: safety, holds, makespan, arrivals, changes.
- :mod:`~fleet.core.planner.rollout`: many small scenes in few simulator calls.
- :mod:`~fleet.core.planner.corridor`: predicted corridors and the check the service runs.
- :mod:`~fleet.core.planner.config`: :class:`PlannerConfig`.
"""

from fleet.core.planner.config import PlannerConfig
from fleet.core.planner.corridor import corridor_distance, left_corridor
from fleet.core.planner.model import (
    Action,
    Plan,
    PlanningSnapshot,
    RobotSnapshot,
    TaskDecision,
    TaskSnapshot,
)
from fleet.core.planner.plan import plan

__all__ = [
    "Action",
    "Plan",
    "PlannerConfig",
    "PlanningSnapshot",
    "RobotSnapshot",
    "TaskDecision",
    "TaskSnapshot",
    "corridor_distance",
    "left_corridor",
    "plan",
]
