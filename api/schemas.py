"""Request (``...In``) and response (``...Out``) models of the REST API.

Input models are strict (``extra="forbid"``, finite numbers, bounded values) so bad input
is a 422 naming the field, never a 500 further down. Obstacle centres outside the yard
(which depends on the settings) are 422s too, from :func:`yard_errors` in ``api.deps``; a
goal outside the yard is well-formed but rejected by the service (409 with the reason), as
a goal in an obstacle's zone is.
The domain models (``fleet.core.tasks``) stay the service's business; these are the contract.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from fleet.core.params import Gains, Tolerance
from fleet.core.tasks import Direction, RobotStatus, RobotView, Task, TaskRequest, TaskStatus
from fleet.core.types import Law
from fleet.core.wire import (
    DEFAULT_OBSTACLE_BODY_M,
    ControlAction,
    ControlCommand,
    ErrorLevel,
    Obstacle,
    Pose,
    RobotError,
    RobotId,
)
from fleet.service.bays import BayState
from fleet.service.stats import PlannerStats
from fleet.service.zones import ZoneState

Coordinate = Annotated[
    float, Field(allow_inf_nan=False, description="metres, inside the yard (see /healthz)")
]
GoalCoordinate = Annotated[
    float,
    Field(
        allow_inf_nan=False,
        description="metres; a goal outside the yard (see /healthz) is rejected (409)",
    ),
]
Heading = Annotated[
    float,
    Field(ge=-2 * math.pi, le=2 * math.pi, allow_inf_nan=False, description="radians"),
]
Gain = Annotated[float, Field(gt=0.0, le=100.0, allow_inf_nan=False)]

Yard = tuple[float, float, float, float]


class _In(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PoseIn(_In):
    """Goal posture in the world frame: x, y [m] inside the yard, theta [rad]."""

    x: GoalCoordinate
    y: GoalCoordinate
    theta: Heading = 0.0


class GainsIn(_In):
    """Controller gains kx [1/s], ky, ktheta of laws (17)/(20); each in (0, 100]."""

    kx: Gain
    ky: Gain
    ktheta: Gain


class ToleranceIn(_In):
    """Arrival tolerance: position [m] and heading [rad]."""

    position: Annotated[float, Field(ge=0.001, le=10.0, allow_inf_nan=False)] = 0.1
    heading: Annotated[float, Field(ge=0.001, le=math.pi, allow_inf_nan=False)] = 0.1


BayName = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")]


class TaskIn(_In):
    """Park a robot (the named one, or any) at ``goal``, in the named ``bay``, or in any
    free bay of ``bay_group``: exactly one of the three."""

    model_config = ConfigDict(
        extra="forbid",
        frozen=True,
        json_schema_extra={
            "examples": [
                {"goal": {"x": 3.0, "y": 2.0, "theta": 1.57}},
                {"bay": "A3"},
                {"bay_group": "charging", "robot_id": "robot-2"},
            ]
        },
    )

    goal: PoseIn | None = Field(default=None, description="a parking posture")
    bay: BayName | None = Field(default=None, description="a bay of the site map (GET /bays)")
    bay_group: BayName | None = Field(
        default=None, description="any free bay of this group, e.g. charging"
    )
    robot_id: RobotId | None = Field(default=None, description="a specific robot; omit for any")
    direction: Direction = Field(
        default="auto", description="auto: the fleet picks cw/ccw; cw = law (20), ccw = law (17)"
    )
    gains: GainsIn | None = Field(default=None, description="omit for the law's default gains")
    tolerance: ToleranceIn = ToleranceIn()

    @model_validator(mode="after")
    def _one_target(self) -> TaskIn:
        given = [n for n in ("goal", "bay", "bay_group") if getattr(self, n) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of goal, bay, bay_group (got {len(given)})")
        return self

    def to_request(self, goal: Pose | None = None, bay: str | None = None) -> TaskRequest:
        """The request, at ``goal`` (a bay's pose) or else at the body's goal."""
        if goal is None:
            assert self.goal is not None
            goal = Pose(x=self.goal.x, y=self.goal.y, theta=self.goal.theta)
        return TaskRequest(
            goal=goal,
            robot_id=self.robot_id,
            direction=self.direction,
            gains=None if self.gains is None else Gains(**self.gains.model_dump()),
            tolerance=Tolerance(**self.tolerance.model_dump()),
            bay=bay,
        )


class ControlIn(_In):
    """Whom an operator command is for, and why."""

    model_config = ConfigDict(
        extra="forbid",
        frozen=True,
        json_schema_extra={"examples": [{"reason": "drill"}, {"robot_id": "robot-2"}]},
    )

    robot_id: RobotId | None = Field(default=None, description="one robot; omit for the fleet")
    reason: Annotated[str, Field(max_length=200)] | None = Field(
        default=None, description="shown in the robots' state (detail) and errors"
    )


class ObstacleIn(_In):
    """A static obstacle: a post at (x, y), or with ``end`` a wall segment from (x, y) to
    ``end`` (both inside the yard) [m]; influence radius [m] of Eq. (27) and body radius
    [m] (a wall's half thickness) that robots keep ``contact_margin_m`` from."""

    x: Coordinate
    y: Coordinate
    radius: Annotated[float, Field(gt=0.0, le=20.0, allow_inf_nan=False)] = 1.0
    body: Annotated[float, Field(ge=0.0, le=20.0, allow_inf_nan=False)] | None = Field(
        default=None,
        description="solid radius [m], at most the influence radius; omitted: "
        f"{DEFAULT_OBSTACLE_BODY_M} m (a post)",
    )

    end: tuple[Coordinate, Coordinate] | None = Field(
        default=None, description="[x, y] of a wall segment's far end [m]; omitted: a post"
    )

    @model_validator(mode="after")
    def _body_within_influence(self) -> ObstacleIn:
        if self.body is not None and self.body > self.radius:
            raise ValueError(f"body: {self.body} m exceeds the influence radius {self.radius} m")
        return self

    def to_obstacle(self) -> Obstacle:
        return Obstacle(x=self.x, y=self.y, radius=self.radius, body=self.body, end=self.end)


ObstaclesIn = Annotated[list[ObstacleIn], Field(max_length=1000)]


def yard_errors(points: list[tuple[tuple[str | int, ...], float, float]], yard: Yard) -> list[Any]:
    """Validation errors (FastAPI's format) for the points ``(loc, x, y)`` outside the yard."""
    xmin, xmax, ymin, ymax = yard
    errors: list[Any] = []
    for loc, x, y in points:
        for name, value, low, high in (("x", x, xmin, xmax), ("y", y, ymin, ymax)):
            if not low <= value <= high:
                errors.append(
                    {
                        "type": "outside_yard",
                        "loc": (*loc, name),
                        "msg": f"{name}={value:g} is outside the yard [{low:g}, {high:g}]",
                        "input": value,
                    }
                )
    return errors


# --- responses ------------------------------------------------------------------------


class PoseOut(BaseModel):
    x: float
    y: float
    theta: float

    @classmethod
    def of(cls, pose: Pose) -> PoseOut:
        return cls(x=pose.x, y=pose.y, theta=pose.theta)


class PointOut(BaseModel):
    """A point of the world frame [m]."""

    x: float
    y: float


class TaskOut(BaseModel):
    """A parking task as the fleet knows it."""

    id: str
    status: TaskStatus
    goal: PoseOut
    direction: Direction
    requested_robot_id: str | None = Field(description="the robot asked for, if any")
    robot_id: str | None = Field(description="the robot doing it, once assigned")
    law: Law | None = Field(description="chosen law: cw = (20), ccw = (17)")
    gains: Gains | None
    tolerance: Tolerance
    reason: str | None = Field(description="why it failed or was cancelled")
    bay: str | None = Field(default=None, description="the bay the task parks in (reserved)")
    attempts: int
    revision: int = Field(
        description="re-plans of the law while under way (0 as first sent); each one is "
        "sent to the robot as a new revision of its assignment"
    )
    route: list[PointOut] = Field(
        default_factory=list,
        description="via-points the robot was sent to pass, in order, before the goal "
        "(around walls and posts; empty: straight to the goal); each revision replaces it",
    )
    created_at: float = Field(description="seconds since the epoch")
    updated_at: float = Field(description="seconds since the epoch")

    @classmethod
    def of(cls, task: Task) -> TaskOut:
        req = task.request
        return cls(
            id=task.id,
            status=task.status,
            goal=PoseOut.of(req.goal),
            direction=req.direction,
            requested_robot_id=req.robot_id,
            robot_id=task.robot_id,
            law=task.law,
            gains=req.gains,
            tolerance=req.tolerance,
            reason=task.reason,
            bay=req.bay,
            attempts=task.attempts,
            revision=task.revision,
            route=[PointOut(x=x, y=y) for x, y in task.route],
            created_at=task.created_at,
            updated_at=task.updated_at,
        )


class TaskEventOut(BaseModel):
    """One stored transition of a task."""

    at: float = Field(description="seconds since the epoch (service clock)")
    event: str = Field(
        description="created, assigned, acknowledged, replanned, requeued, succeeded, failed, "
        "cancelled, ..."
    )
    status: TaskStatus
    robot_id: str | None
    law: Law | None = Field(description="cw = (20), ccw = (17)")
    revision: int = Field(description="re-plans of the law while under way")
    attempts: int = Field(description="times the task was assigned (requeues and recoveries)")
    reason: str | None

    @classmethod
    def of(cls, at: float, event: str, task: Task) -> TaskEventOut:
        return cls(
            at=at,
            event=event,
            status=task.status,
            robot_id=task.robot_id,
            law=task.law,
            revision=task.revision,
            attempts=task.attempts,
            reason=task.reason,
        )


class RobotErrorOut(BaseModel):
    """One active fault of a robot."""

    code: str = Field(description="stable code: estop, pose_stale, link_lost, drive_error, ...")
    level: ErrorLevel
    message: str
    since: float = Field(description="when it began, seconds since the epoch (robot clock)")

    @classmethod
    def of(cls, error: RobotError) -> RobotErrorOut:
        return cls(code=error.code, level=error.level, message=error.message, since=error.since)


class RobotOut(BaseModel):
    """The fleet's latest knowledge of one robot."""

    robot_id: str
    status: RobotStatus
    pose: PoseOut
    u: float = Field(description="forward speed [m/s]")
    omega: float = Field(description="turn rate [rad/s]")
    task_id: str | None
    law: Law | None
    goal: PoseOut | None
    radius: float = Field(description="body radius [m]")
    last_seen: float = Field(description="seconds since the epoch (service clock)")
    detail: str | None = Field(
        default=None, description="why it stands still, e.g. 'pose stale' while holding"
    )
    errors: list[RobotErrorOut] = Field(default_factory=list, description="active faults")
    in_service: bool = Field(default=True, description="false: decommissioned, gets no task")
    described: bool = Field(
        default=False,
        description="it published its RobotDescription; false: planned with the host profile",
    )
    max_wheel_speed: float | None = Field(
        default=None, description="described wheel-speed limit [rad/s]; null: none or unknown"
    )
    max_speed: float | None = Field(
        default=None, description="described top forward speed [m/s]; null: none or unknown"
    )
    may_reverse: bool = Field(
        default=True, description="false: it may not drive backwards, the fleet assigns it nothing"
    )
    model: str | None = Field(default=None, description="described model, e.g. 'TurtleBot 4'")

    @classmethod
    def of(cls, robot: RobotView) -> RobotOut:
        return cls(
            robot_id=robot.robot_id,
            status=robot.status,
            pose=PoseOut.of(robot.pose),
            u=robot.u,
            omega=robot.omega,
            task_id=robot.task_id,
            law=robot.law,
            goal=None if robot.goal is None else PoseOut.of(robot.goal),
            radius=robot.radius,
            last_seen=robot.last_seen,
            detail=robot.detail,
            errors=[RobotErrorOut.of(e) for e in robot.errors],
            in_service=robot.in_service,
            described=robot.described,
            max_wheel_speed=robot.max_wheel_speed,
            max_speed=robot.max_speed,
            may_reverse=robot.may_reverse,
            model=robot.model,
        )


class ControlOut(BaseModel):
    """The command sent to the robots (``ControlCommand`` on the Zenoh control key)."""

    command: ControlAction
    robot_id: str | None = Field(description="the robot, or null for the whole fleet")
    issuer: str
    seq: int
    stamp: float = Field(description="seconds since the epoch")
    reason: str | None

    @classmethod
    def of(cls, message: ControlCommand) -> ControlOut:
        return cls(
            command=message.command,
            robot_id=message.robot_id,
            issuer=message.issuer,
            seq=message.seq,
            stamp=message.stamp,
            reason=message.reason,
        )


class BayOut(BaseModel):
    """A bay of the site map and its state."""

    name: str
    group: str | None
    pose: PoseOut
    status: Literal["free", "reserved", "occupied"] = Field(
        description="reserved: by an active task; occupied: a robot parked in it"
    )
    task_id: str | None = Field(description="the task that reserves it")
    robot_id: str | None = Field(description="the robot driving there or parked in it")

    @classmethod
    def of(cls, state: BayState) -> BayOut:
        bay = state.bay
        return cls(
            name=bay.name,
            group=bay.group,
            pose=PoseOut.of(bay.pose),
            status=state.status,
            task_id=state.task_id,
            robot_id=state.robot_id,
        )


class ZoneOut(BaseModel):
    """A single-robot zone: one robot at a time drives in it (or, with ``convoys``, robots
    going the same way, one behind the other)."""

    name: str
    polygon: list[tuple[float, float]] = Field(description="outline (x, y) [m], world frame")
    found: bool = Field(
        description="a narrow passage found in the walls and posts (else: the site map's)"
    )
    convoys: bool = Field(description="robots going the same way may follow each other in it")
    robot_ids: list[str] = Field(description="the robots holding it (driving through, or in it)")
    task_ids: list[str] = Field(description="their tasks under way")

    @classmethod
    def of(cls, state: ZoneState) -> ZoneOut:
        zone = state.zone
        return cls(
            name=zone.name,
            polygon=[(round(x, 3), round(y, 3)) for x, y in zone.outline],
            found=zone.found,
            convoys=zone.convoys,
            robot_ids=list(state.robot_ids),
            task_ids=list(state.task_ids),
        )


class HoldOut(BaseModel):
    """What the operator asked of the fleet or of one robot."""

    paused: bool
    estop: bool


class ControlStateOut(BaseModel):
    """The operator's holds: fleet-wide, and robots with a command of their own since."""

    fleet: HoldOut
    robots: dict[str, HoldOut]


class ObstacleOut(BaseModel):
    x: float
    y: float
    radius: float = Field(description="influence radius of Eq. (27) [m]")
    body: float = Field(description="body radius [m] (the default when none was given)")
    end: tuple[float, float] | None = Field(
        default=None, description="a wall segment's far end [m]; null: a post"
    )

    @classmethod
    def of(cls, obstacle: Obstacle) -> ObstacleOut:
        return cls(
            x=obstacle.x, y=obstacle.y, radius=obstacle.radius, body=obstacle.body_radius,
            end=obstacle.end,
        )  # fmt: skip


class PathPointOut(BaseModel):
    """One sample of a robot's trajectory while it worked on a task."""

    t: float = Field(description="seconds since the epoch")
    x: float
    y: float
    theta: float
    u: float
    omega: float


class PlannerOut(BaseModel):
    """How planning goes: latency over the last plans, fallbacks, what was dropped."""

    plans: int = Field(description="plans made since the service started")
    window: int = Field(description="plans the latency percentiles are taken over (the latest)")
    p50_ms: float | None = Field(description="median planning time [ms]; null before a plan")
    p99_ms: float | None = Field(description="99th percentile planning time [ms]")
    fallbacks: int = Field(description="robots held (task waiting) for want of a safe option")
    rebased: int = Field(description="plans on a stale snapshot applied in part")
    stale_dropped: int = Field(description="plans on a stale snapshot dropped whole")
    decisions_stale_dropped: int = Field(description="decisions on tasks changed meanwhile")
    unsafe_dropped: int = Field(
        description="decisions that would have started a robot in a plan predicted to come "
        "closer than the separation (never sent; the robots' safety filter acts regardless)"
    )
    relaxed: int = Field(
        description="plans made at the standstill margin because no robot could move "
        "keeping the separation (also parkfleet_service_events_total{event=plans_relaxed})"
    )

    @classmethod
    def of(cls, stats: PlannerStats) -> PlannerOut:
        return cls(**asdict(stats))


class HealthOut(BaseModel):
    status: Literal["ok"] = "ok"
    robots: int
    yard: Yard = Field(description="xmin, xmax, ymin, ymax [m]")
    zenoh: list[str] = Field(description="endpoints the fleet's Zenoh router listens on")
    auth: bool = Field(description="mutating endpoints need a bearer token")
    counters: dict[str, int]
    planner: PlannerOut
    sizes: dict[str, int] = Field(
        description="entries held by the service's bounded structures (robots, active tasks, "
        "recorded path samples, queued effects ...)"
    )
    store: Literal["sqlite", "postgresql"] = "sqlite"
    role: Literal["leader", "standby"] = Field(
        "leader", description="a standby serves reads and answers writes with 503 + the leader"
    )
    term: int = Field(0, description="fencing term of the current leader (0: no election)")
    leader: str | None = Field(None, description="API address of the current leader")
    service: str | None = Field(None, description="this service's own name (host:pid)")


class ErrorOut(BaseModel):
    """Body of every error response."""

    detail: str


class FieldError(BaseModel):
    loc: list[str | int]
    msg: str
    type: str


class ValidationErrorOut(BaseModel):
    """Body of a 422: ``detail`` names the fields, ``errors`` lists them."""

    detail: str
    errors: list[FieldError]
