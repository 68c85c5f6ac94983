"""The fleet planner: snapshot in, plan out (pure; run by the service on its own thread).

- :mod:`~fleet.core.planner.model`: the snapshot it reads and the decisions it makes.
- :mod:`~fleet.core.planner.plan`: :func:`plan`, assignment plus direction choice.
"""

from fleet.core.planner.model import (
    Action,
    Plan,
    PlanningSnapshot,
    RobotSnapshot,
    TaskDecision,
    TaskSnapshot,
)
from fleet.core.planner.plan import PlannerConfig, plan

__all__ = [
    "Action",
    "Plan",
    "PlannerConfig",
    "PlanningSnapshot",
    "RobotSnapshot",
    "TaskDecision",
    "TaskSnapshot",
    "plan",
]
