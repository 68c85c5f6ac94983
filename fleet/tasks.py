"""Task and robot models of the fleet service, and its domain errors.

Shared by the service (``fleet.service``), the store (``fleet.store``) and the API.
Pure module: no I/O, no clock.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from fleet.control import Law
from fleet.params import Gains, Tolerance
from fleet.wire import Pose, RobotId, RobotMode

Direction = Literal["auto", "cw", "ccw"]


class TaskStatus(StrEnum):
    """Life cycle: queued -> assigned -> driving -> succeeded | failed | cancelled."""

    QUEUED = "queued"
    ASSIGNED = "assigned"
    DRIVING = "driving"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def final(self) -> bool:
        return self in (TaskStatus.SUCCEEDED, TaskStatus.FAILED, TaskStatus.CANCELLED)


class RobotStatus(StrEnum):
    """Fleet view of a robot: what it reports, or ``lost`` when its liveliness token is gone."""

    IDLE = "idle"
    DRIVING = "driving"
    AVOIDING = "avoiding"
    ARRIVED = "arrived"
    HOLDING = "holding"
    LOST = "lost"

    @classmethod
    def from_mode(cls, mode: RobotMode) -> RobotStatus:
        return cls(mode.value)


#: Default gains per law when a task names none (the paper's Table 1, first scenario).
DEFAULT_GAINS: dict[Law, Gains] = {
    "ccw": Gains(kx=2.6, ky=1.5, ktheta=1.5),
    "cw": Gains(kx=2.1, ky=1.25, ktheta=1.25),
}


class TaskRequest(BaseModel):
    """What a user asks for: park a robot (named or any) at ``goal``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    goal: Pose
    robot_id: RobotId | None = None
    direction: Direction = "auto"
    gains: Gains | None = None  # None: DEFAULT_GAINS of the chosen law
    tolerance: Tolerance = Tolerance(position=0.1, heading=0.1)


class Task(BaseModel):
    """A task as stored and reported. ``law`` is set once the direction is chosen."""

    model_config = ConfigDict(extra="forbid")

    id: str
    request: TaskRequest
    status: TaskStatus = TaskStatus.QUEUED
    robot_id: str | None = None
    law: Law | None = None
    reason: str | None = None  # why it failed or was cancelled
    created_at: float  # [s since epoch]
    updated_at: float
    attempts: Annotated[int, Field(ge=0)] = 0


class RobotView(BaseModel):
    """The fleet's latest knowledge of one robot."""

    model_config = ConfigDict(extra="forbid")

    robot_id: str
    status: RobotStatus
    pose: Pose
    u: float = 0.0
    omega: float = 0.0
    task_id: str | None = None
    law: Law | None = None
    goal: Pose | None = None
    radius: float = 0.2
    last_seen: float  # [s since epoch], service clock


class FleetError(Exception):
    """Base of the service's domain errors; ``str(err)`` is the user-facing reason."""


class TaskNotFound(FleetError):
    pass


class RobotNotFound(FleetError):
    pass


class GoalRejected(FleetError):
    """The goal is outside the yard, inside an obstacle's zone, or too near another goal."""


class TaskConflict(FleetError):
    """The request conflicts with the task's state (e.g. cancelling a finished task)."""
