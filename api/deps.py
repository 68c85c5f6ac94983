"""Route dependencies as ``Annotated`` aliases: the service, the settings, auth, checked bodies.

The dependencies are ``async`` because none of them blocks: FastAPI would otherwise run
each one in the thread pool. Routes that call the service (which may touch SQLite) are
plain ``def`` and so run in the thread pool, off the event loop.
"""

from __future__ import annotations

import secrets
from collections.abc import Callable
from typing import Annotated, Protocol

from fastapi import Body, Depends, Header, HTTPException, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from api.schemas import ObstacleIn, ObstaclesIn, TaskIn, yard_errors
from fleet.core.tasks import FleetEvent, RobotView, Task, TaskRequest
from fleet.core.wire import ControlAction, ControlCommand, Obstacle, Pose
from fleet.io.settings import Settings
from fleet.service.bays import BayState
from fleet.service.control_desk import ControlState
from fleet.service.stats import PlannerStats
from fleet.service.store import TaskStore
from fleet.service.zones import ZoneState


class FleetAPI(Protocol):
    """What the API needs of :class:`fleet.service.FleetService` (a test double may stand in)."""

    @property
    def counters(self) -> dict[str, int]: ...

    def submit(self, request: TaskRequest, idempotency_key: str | None = None) -> Task: ...
    def cancel(self, task_id: str) -> Task: ...
    def task(self, task_id: str) -> Task: ...
    def history(self, task_id: str) -> list[tuple[float, str, Task]]: ...
    def submit_to_bay(
        self,
        bay: str | None,
        group: str | None,
        make: Callable[[Pose, str], TaskRequest],
        idempotency_key: str | None = None,
    ) -> Task: ...
    def bays(self) -> list[BayState]: ...
    def zones(self) -> list[ZoneState]: ...
    def decommission(self, robot_id: str) -> RobotView: ...
    def commission(self, robot_id: str) -> RobotView: ...
    def robots(self) -> list[RobotView]: ...
    def robot(self, robot_id: str) -> RobotView: ...
    def remove_robot(self, robot_id: str) -> None: ...
    def obstacles(self) -> list[Obstacle]: ...
    def set_obstacles(self, obstacles: list[Obstacle]) -> None: ...
    def path(self, task_id: str) -> list[tuple[float, float, float, float, float, float]]: ...
    def add_listener(self, listener: Callable[[FleetEvent], None]) -> Callable[[], None]: ...
    def control(
        self, action: ControlAction, robot_id: str | None = None, reason: str | None = None
    ) -> ControlCommand: ...
    def control_state(self) -> ControlState: ...
    def planner_stats(self) -> PlannerStats: ...
    def sizes(self) -> dict[str, int]: ...


async def get_service(request: Request) -> FleetAPI:
    service: FleetAPI | None = getattr(request.app.state, "service", None)
    if service is None:  # only between lifespan shutdown and the last request
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, "fleet service not running")
    return service


async def get_task_store(request: Request) -> TaskStore:
    """The service's task store: ``GET /tasks`` reads its pages there, where every
    transition lands before it is announced."""
    tasks: TaskStore | None = getattr(request.app.state, "tasks", None)
    if tasks is None:
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, "task store not open")
    return tasks


async def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


ServiceDep = Annotated[FleetAPI, Depends(get_service)]
TaskStoreDep = Annotated[TaskStore, Depends(get_task_store)]
SettingsDep = Annotated[Settings, Depends(get_settings)]

_bearer = HTTPBearer(auto_error=False, description="PARKFLEET_API_TOKEN, when set")


async def require_token(
    settings: SettingsDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """401 unless ``Authorization: Bearer <PARKFLEET_API_TOKEN>`` (when a token is set)."""
    if settings.api_token is None:
        return
    expected = settings.api_token.get_secret_value().encode()
    given = b"" if credentials is None else credentials.credentials.encode()
    # compare_digest on bytes: constant time in the token's content (length may leak).
    if credentials is None or not secrets.compare_digest(given, expected):
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "missing or wrong bearer token",
            headers={"WWW-Authenticate": "Bearer"},
        )


Authorized = Depends(require_token)
"""Use as ``dependencies=[Authorized]`` on mutating routes."""


async def checked_obstacles(
    body: Annotated[ObstaclesIn, Body()], settings: SettingsDep
) -> ObstaclesIn:
    """The obstacle list, every centre and wall end checked against the configured yard
    (422 otherwise)."""
    points: list[tuple[tuple[str | int, ...], float, float]]
    points = [(("body", i), o.x, o.y) for i, o in enumerate(body)]
    points += [(("body", i, "end"), *o.end) for i, o in enumerate(body) if o.end is not None]
    errors = yard_errors(points, settings.yard)
    if errors:
        raise RequestValidationError(errors)
    return body


TaskBody = Annotated[TaskIn, Body()]
"""A well-formed task body (422 otherwise). Its goal is the service's to judge: one outside
the yard is rejected like one in an obstacle's zone (``GoalRejected``, 409 with the reason)."""
ObstaclesBody = Annotated[list[ObstacleIn], Depends(checked_obstacles)]
IdempotencyKey = Annotated[
    str | None,
    Header(
        alias="Idempotency-Key",
        min_length=1,
        max_length=200,
        description="repeat a POST with the same key to get the same task back",
    ),
]
