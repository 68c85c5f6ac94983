"""``/tasks``: submit, list, read and cancel parking tasks.

Handlers are plain ``def`` on purpose: the service may write SQLite, so FastAPI runs them
in its thread pool instead of on the event loop. Domain errors map to status codes in
``api.errors``.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, status

from api.deps import Authorized, IdempotencyKey, ServiceDep, TaskBody
from api.schemas import ErrorOut, PathPointOut, TaskEventOut, TaskOut
from fleet.core.tasks import TaskStatus

router = APIRouter(prefix="/tasks", tags=["tasks"])

TaskId = Annotated[str, Path(min_length=1, max_length=200)]


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Authorized],
    responses={
        401: {"model": ErrorOut, "description": "missing or wrong bearer token"},
        404: {"model": ErrorOut, "description": "unknown robot, bay or bay group"},
        409: {
            "model": ErrorOut,
            "description": "goal rejected (obstacle or keep-out zone, near a goal), bay taken",
        },
    },
)
def submit_task(
    body: TaskBody, service: ServiceDep, idempotency_key: IdempotencyKey = None
) -> TaskOut:
    """Create a parking task at a goal, in a bay, or in any free bay of a group; it is
    stored before the 201 is sent."""
    if body.goal is not None:
        return TaskOut.of(service.submit(body.to_request(), idempotency_key))
    return TaskOut.of(
        service.submit_to_bay(body.bay, body.bay_group, body.to_request, idempotency_key)
    )


@router.get("")
def list_tasks(
    service: ServiceDep,
    status: TaskStatus | None = None,
    robot_id: Annotated[str | None, Query(max_length=200)] = None,
    limit: Annotated[int | None, Query(ge=1, le=100_000, description="newest N")] = None,
) -> list[TaskOut]:
    """Tasks, oldest first, optionally filtered by status and (assigned) robot."""
    tasks = sorted(service.tasks(status, robot_id), key=lambda t: (t.created_at, t.id))
    if limit is not None:
        tasks = tasks[-limit:]
    return [TaskOut.of(task) for task in tasks]


@router.get("/{task_id}", responses={404: {"model": ErrorOut}})
def get_task(task_id: TaskId, service: ServiceDep) -> TaskOut:
    return TaskOut.of(service.task(task_id))


@router.post(
    "/{task_id}/cancel",
    dependencies=[Authorized],
    responses={
        401: {"model": ErrorOut},
        404: {"model": ErrorOut},
        409: {"model": ErrorOut, "description": "the task is already finished"},
    },
)
def cancel_task(task_id: TaskId, service: ServiceDep) -> TaskOut:
    return TaskOut.of(service.cancel(task_id))


#: Most transitions returned by ``/tasks/{id}/events`` (the newest).
HISTORY_MAX = 1000


@router.get("/{task_id}/events", responses={404: {"model": ErrorOut}})
def task_events(task_id: TaskId, service: ServiceDep) -> list[TaskEventOut]:
    """Every transition of the task, oldest first (at most the newest 1000): time, event,
    status, robot, law, revision, attempts, reason."""
    rows = service.history(task_id)[-HISTORY_MAX:]
    return [TaskEventOut.of(at, event, task) for at, event, task in rows]


@router.get("/{task_id}/path", responses={404: {"model": ErrorOut}})
def task_path(task_id: TaskId, service: ServiceDep) -> list[PathPointOut]:
    """The trajectory the fleet saw while a robot worked on the task."""
    return [
        PathPointOut(t=t, x=x, y=y, theta=theta, u=u, omega=omega)
        for t, x, y, theta, u, omega in service.path(task_id)
    ]
