"""``/tasks``: submit, list, read and cancel parking tasks.

Handlers are plain ``def`` on purpose: the service may write SQLite, so FastAPI runs them
in its thread pool instead of on the event loop. Domain errors map to status codes in
``api.errors``. The list is paged in SQL (``TaskStore.list``): at most ``limit`` tasks
(``api_tasks_page_max`` at most), the next page named by the ``Link: <…>; rel="next"``
header, so a listing costs the same with ten tasks stored or ten million.
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Path, Query, Request, Response, status
from fastapi.exceptions import RequestValidationError

from api.deps import Authorized, IdempotencyKey, ServiceDep, SettingsDep, TaskBody, TaskStoreDep
from api.paging import decode_cursor, encode_cursor
from api.schemas import ErrorOut, PathPointOut, TaskEventOut, TaskOut
from fleet.core.tasks import Task, TaskStatus
from fleet.service.store import TaskCursor

router = APIRouter(prefix="/tasks", tags=["tasks"])

TaskId = Annotated[str, Path(min_length=1, max_length=200)]

#: Tasks in a page when the client does not say (never more than ``api_tasks_page_max``).
DEFAULT_PAGE = 100


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=TaskOut,
    dependencies=[Authorized],
    responses={
        401: {"model": ErrorOut, "description": "missing or wrong bearer token"},
        404: {"model": ErrorOut, "description": "unknown robot, bay or bay group"},
        409: {
            "model": ErrorOut,
            "description": "goal rejected (outside the yard, in an obstacle's or keep-out "
            "zone, near a goal), bay taken, robot decommissioned; the reason in `detail`",
        },
    },
)
def submit_task(
    body: TaskBody, service: ServiceDep, idempotency_key: IdempotencyKey = None
) -> Response:
    """Create a parking task at a goal, in a bay, or in any free bay of a group; it is
    stored before the 201 is sent."""
    if body.goal is not None:
        task = service.submit(body.to_request(), idempotency_key)
    else:
        task = service.submit_to_bay(body.bay, body.bay_group, body.to_request, idempotency_key)
    # Serialised once, here (``response_model`` documents it): returned as a model, FastAPI
    # would validate it against TaskOut again before serialising it, ~15 % of the app's CPU
    # a POST (the busiest route: docs/benchmarks.md, ``bench api``).
    out = TaskOut.of(task).model_dump_json()
    return Response(out, status.HTTP_201_CREATED, media_type="application/json")


@router.get(
    "",
    responses={
        200: {
            "description": "a page of tasks; when more follow, a `Link` header names the "
            'next page: `<URL>; rel="next"`',
        },
    },
)
def list_tasks(
    request: Request,
    response: Response,
    tasks: TaskStoreDep,
    settings: SettingsDep,
    status: TaskStatus | None = None,
    robot_id: Annotated[str | None, Query(max_length=200)] = None,
    order: Annotated[
        Literal["oldest", "newest"], Query(description="oldest first (default) or newest first")
    ] = "oldest",
    limit: Annotated[
        int | None,
        Query(ge=1, description=f"page size (default {DEFAULT_PAGE}, at most api_tasks_page_max)"),
    ] = None,
    cursor: Annotated[
        str | None, Query(max_length=512, description="the next page, from the Link header")
    ] = None,
) -> list[TaskOut]:
    """A page of tasks in creation order, optionally filtered by status and robot (the
    assigned one, else the one asked for)."""
    page_max = settings.api_tasks_page_max
    if limit is not None and limit > page_max:
        raise RequestValidationError(
            [{"type": "less_than_equal", "loc": ("query", "limit"),
              "msg": f"at most {page_max} tasks a page (api_tasks_page_max)"}]
        )  # fmt: skip
    page = min(limit or DEFAULT_PAGE, page_max)
    after: TaskCursor | None = None
    if cursor is not None:
        try:
            after = decode_cursor(cursor)
        except ValueError as exc:
            raise RequestValidationError(
                [{"type": "value_error", "loc": ("query", "cursor"), "msg": str(exc)}]
            ) from None
    found = tasks.list(
        status, robot_id, after=after, limit=page + 1, newest_first=order == "newest"
    )
    if len(found) > page:  # one more than the page: there is a next one
        found = found[:page]
        following = request.url.include_query_params(cursor=encode_cursor(found[-1]), limit=page)
        response.headers["Link"] = f'<{following}>; rel="next"'
    return [TaskOut.of(task) for task in found]


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


@router.get(
    "/{task_id}/path",
    responses={
        404: {"model": ErrorOut, "description": "unknown task"},
        409: {"model": ErrorOut, "description": "no recorded path (yet, or any more)"},
    },
)
def task_path(task_id: TaskId, service: ServiceDep) -> list[PathPointOut]:
    """The trajectory the fleet saw while a robot worked on the task; 409 while none is
    recorded (no robot has driven it yet, or its path was evicted)."""
    samples = service.path(task_id)  # 404 when unknown
    if not samples:
        raise HTTPException(status.HTTP_409_CONFLICT, no_path_reason(service.task(task_id)))
    return [
        PathPointOut(t=t, x=x, y=y, theta=theta, u=u, omega=omega)
        for t, x, y, theta, u, omega in samples
    ]


def no_path_reason(task: Task) -> str:
    """Why ``task`` has no path to show (the 409 of ``/path`` and ``/plot.png``)."""
    return (
        f"task {task.id} has no recorded path ({task.status.value}): a path is recorded "
        "while a robot drives the task, and only for the most recent tasks"
    )
