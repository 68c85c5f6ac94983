"""Task and robot models of the fleet service, and its domain errors.

Shared by the service (``fleet.service``), its store and the API.
Pure module: no I/O, no clock.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from fleet.core.params import Gains, Tolerance
from fleet.core.types import Law
from fleet.core.wire import (
    DEFAULT_PASS_M,
    MAX_ROUTE_POINTS,
    Pose,
    RobotError,
    RobotId,
    RobotMode,
    ViaPoint,
)

Direction = Literal["auto", "cw", "ccw"]


class TaskStatus(StrEnum):
    """Life cycle: queued -> assigned -> driving -> succeeded | failed | cancelled.

    ``waiting``: the task has its robot, which stands still because the planner found no
    safe option yet (``reason`` says why); it becomes ``driving`` again once released.
    """

    QUEUED = "queued"
    ASSIGNED = "assigned"
    DRIVING = "driving"
    WAITING = "waiting"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def final(self) -> bool:
        return self in (TaskStatus.SUCCEEDED, TaskStatus.FAILED, TaskStatus.CANCELLED)

    @property
    def under_way(self) -> bool:
        """The task has a robot: assigned, driving or waiting."""
        return self in (TaskStatus.ASSIGNED, TaskStatus.DRIVING, TaskStatus.WAITING)


class RobotStatus(StrEnum):
    """Fleet view of a robot: what it reports, or ``lost`` when its liveliness token is gone."""

    IDLE = "idle"
    DRIVING = "driving"
    AVOIDING = "avoiding"
    ARRIVED = "arrived"
    HOLDING = "holding"
    WAITING = "waiting"
    PAUSED = "paused"
    ESTOP = "estop"
    LOST = "lost"

    @classmethod
    def from_mode(cls, mode: RobotMode) -> RobotStatus:
        return cls(mode.value)


#: Default gains per law when a task names none, from ``parkfleet tune yard --law ccw|cw
#: --generations 15 --popsize 8`` (rounded to 3 digits): typical yard trips (10 m x 10 m,
#: random headings) for the Table 10 robot at its 20 rad/s wheel limit, 50 Hz, 0.1 m /
#: 0.1 rad, time first with every whole turn priced at 2 s; kx capped at Table 1's so Eq.
#: (27)'s standoff between robots is unchanged. On 1000 held-out trips (mean 5.4 m) they
#: arrive in 9.6 s (ccw) and 10.3 s (cw) on average, turning 1.6 and 1.5 revolutions a
#: trip; the time-first gains before them (2.6, 72.4, 9.56) and (2.1, 129, 12.2) took 9.4 s
#: and 10.0 s but spun 1.9 and 2.9 revolutions, and a fleet of them stopped and turned
#: (docs/paper.md).
DEFAULT_GAINS: dict[Law, Gains] = {
    "ccw": Gains(kx=2.59, ky=11.4, ktheta=10.0),
    "cw": Gains(kx=2.06, ky=3.78, ktheta=8.72),
}


class TaskRequest(BaseModel):
    """What a user asks for: park a robot (named or any) at ``goal``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    goal: Pose
    robot_id: RobotId | None = None
    direction: Direction = "auto"
    gains: Gains | None = None  # None: law_gains, else DEFAULT_GAINS of the chosen law
    tolerance: Tolerance = Tolerance(position=0.1, heading=0.1)
    #: Gains per law, used when ``gains`` is None (e.g. ``auto`` with the paper's per-law
    #: gains of Table 8); a law missing here falls back to DEFAULT_GAINS.
    law_gains: dict[Law, Gains] | None = None
    #: The site's bay whose pose is ``goal`` (reserved by this task while it is active).
    bay: str | None = None

    def gains_for(self, law: Law) -> Gains:
        """The gains the robot uses with ``law``: gains, else law_gains[law], else default."""
        if self.gains is not None:
            return self.gains
        if self.law_gains is not None and law in self.law_gains:
            return self.law_gains[law]
        return DEFAULT_GAINS[law]


class Task(BaseModel):
    """A task as stored and reported. ``law`` is set once the direction is chosen."""

    model_config = ConfigDict(extra="forbid")

    id: str
    request: TaskRequest
    status: TaskStatus = TaskStatus.QUEUED
    robot_id: str | None = None
    law: Law | None = None
    reason: str | None = None  # why it failed, was cancelled, or waits
    created_at: float  # [s since epoch]
    updated_at: float
    attempts: Annotated[int, Field(ge=0)] = 0
    #: Re-plans of the law while under way (``ParkAssignment.revision``); 0 as first sent.
    revision: Annotated[int, Field(ge=0)] = 0
    #: What the robot was last told besides the law (``ParkAssignment``): stand still this
    #: long [s, robot time] before driving, or hold until a later revision (``waiting``).
    start_delay_s: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 0.0
    hold: bool = False
    #: Via-points the robot was sent to pass before the goal, and their pass-through radius
    #: [m] (``ParkAssignment.route``, ``pass_m``); empty: straight to the goal.
    route: Annotated[list[ViaPoint], Field(max_length=MAX_ROUTE_POINTS)] = Field(
        default_factory=list
    )
    pass_m: Annotated[float, Field(gt=0, allow_inf_nan=False)] = DEFAULT_PASS_M


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
    detail: str | None = None  # why it stands still (RobotState.detail)
    in_service: bool = True  # False: decommissioned by an operator (gets no task)
    errors: list[RobotError] = Field(default_factory=list)  # active faults, oldest first
    #: The robot published a ``RobotDescription``; False: planned with the host's profile.
    described: bool = False
    max_wheel_speed: float | None = None  # [rad/s] described limit; None: none or unknown
    max_speed: float | None = None  # [m/s] top forward speed described; None: none/unknown
    may_reverse: bool = True  # described: its base may drive backwards
    model: str | None = None  # described model name, for people


class RobotEvent(BaseModel):
    """A robot's view changed (status, task, or a throttled pose update)."""

    model_config = ConfigDict(extra="forbid")

    type: Literal["robot"] = "robot"
    robot: RobotView


class TaskEvent(BaseModel):
    """A task changed state; sent only after the change is stored."""

    model_config = ConfigDict(extra="forbid")

    type: Literal["task"] = "task"
    task: Task


#: What :meth:`fleet.service.FleetService.add_listener` callbacks receive. A plain union,
#: so ``isinstance(event, FleetEvent)`` works; serialise with ``event.model_dump_json()``.
FleetEvent = RobotEvent | TaskEvent


class FleetError(Exception):
    """Base of the service's domain errors; ``str(err)`` is the user-facing reason."""


class TaskNotFound(FleetError):
    pass


class RobotNotFound(FleetError):
    pass


class GoalRejected(FleetError):
    """The goal is outside the yard, inside an obstacle's zone, or too near another goal."""


class BayNotFound(FleetError):
    """No such bay or bay group in the site map."""


class BayTaken(FleetError):
    """The bay is reserved by another active task (or every bay of the group is taken)."""


class TaskConflict(FleetError):
    """The request conflicts with the task's state (e.g. cancelling a finished task)."""


class RobotConflict(FleetError):
    """The request conflicts with the robot's state (e.g. removing a robot still alive)."""
