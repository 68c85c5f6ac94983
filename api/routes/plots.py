"""``/tasks/{id}/plot.png``: a task's recorded path and control signals, as ``parkfleet plot``.

The fleet service records the task's robot as its states arrive (``FleetService.path``):
irregular samples on the service's wall clock. They are resampled onto a uniform time grid
(at most :data:`MAX_STEPS` steps) for :func:`fleet.drawing.plot_trajectory`, which draws the
path with oriented triangles as in the paper's figures, and u, omega over time.
Images are cached and renders rate-limited (:mod:`api.plot_cache`): 429 when over the rate.
"""

from __future__ import annotations

import io
from typing import Annotated

import numpy as np
import numpy.typing as npt
from fastapi import APIRouter, HTTPException, Path, Request, Response, status

from api.deps import ServiceDep
from api.errors import retry_later
from api.plot_cache import PlotCache, RenderLimited
from api.routes.tasks import no_path_reason
from api.schemas import ErrorOut

router = APIRouter(prefix="/tasks", tags=["tasks"])

#: Steps of the resampled trajectory (enough for a smooth 700-pixel-wide figure).
MAX_STEPS = 2000

PathSamples = list[tuple[float, float, float, float, float, float]]


def resample(
    samples: PathSamples, max_steps: int = MAX_STEPS
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float]:
    """Uniformly resampled ``(poses (T+1, 3), controls (T, 2), dt [s])`` of path samples.

    ``samples`` are ``(t, x, y, theta, u, omega)`` with increasing ``t``; theta is unwrapped
    before interpolation so a heading crossing ±π does not swing round the circle. Needs at
    least two samples.
    """
    data = np.asarray(samples, dtype=np.float64)
    if data.ndim != 2 or data.shape[0] < 2 or data.shape[1] != 6:
        raise ValueError("need at least two (t, x, y, theta, u, omega) samples")
    t = data[:, 0] - data[0, 0]
    keep = np.concatenate([[True], np.diff(t) > 0])  # interp needs increasing t
    data, t = data[keep], t[keep]
    if t.size < 2:
        raise ValueError("the samples span no time")
    steps = int(min(max_steps, t.size - 1)) or 1
    grid = np.linspace(0.0, float(t[-1]), steps + 1)
    theta = np.unwrap(data[:, 3])
    poses = np.column_stack(
        [np.interp(grid, t, data[:, k]) for k in (1, 2)] + [np.interp(grid, t, theta)]
    )
    controls = np.column_stack([np.interp(grid[:-1], t, data[:, k]) for k in (4, 5)])
    return poses, controls, float(grid[1] - grid[0])


@router.get(
    "/{task_id}/plot.png",
    response_class=Response,
    responses={
        200: {"content": {"image/png": {}}, "description": "path and control signals"},
        404: {"model": ErrorOut, "description": "unknown task"},
        409: {"model": ErrorOut, "description": "no recorded path (yet, or any more)"},
        429: {"model": ErrorOut, "description": "too many plots rendered lately (Retry-After)"},
    },
)
def task_plot(
    task_id: Annotated[str, Path(min_length=1, max_length=200)],
    service: ServiceDep,
    request: Request,
) -> Response:
    """PNG of the task robot's recorded path (oriented triangles) and its u, ω over time.

    Time is the fleet service's clock from the first recorded sample; the path is recorded
    while the robot works on the task, so it grows until the task finishes.
    """
    # Plain def: matplotlib rendering is CPU work, kept off the event loop. Only the
    # object-oriented Figure API is used (no pyplot state), so threads do not interfere.
    from fleet.drawing import LAW_EQUATION, plot_trajectory

    task = service.task(task_id)  # 404 when unknown
    samples = service.path(task_id)
    plots: PlotCache = request.app.state.plots
    # What the image shows: the task's title fields and the path so far.
    key = (task.id, task.status, task.law, task.robot_id, len(samples), tuple(samples[-1:]))
    image = plots.get(key)
    if image is None:
        try:
            poses, controls, dt = resample(samples)
        except ValueError:
            raise HTTPException(status.HTTP_409_CONFLICT, no_path_reason(task)) from None
        goal = task.request.goal
        law = f"law {task.law}, {LAW_EQUATION[task.law]}" if task.law else "law not chosen"
        title = f"task {task.id[:8]} · {task.robot_id or 'no robot'}\n{law} · {task.status.value}"

        def draw() -> bytes:
            fig = plot_trajectory(poses, controls, dt, [goal.x, goal.y, goal.theta], title)
            buffer = io.BytesIO()
            fig.savefig(buffer, format="png", dpi=100)
            return buffer.getvalue()

        try:
            image = plots.render(key, draw)
        except RenderLimited as exc:
            raise retry_later(
                status.HTTP_429_TOO_MANY_REQUESTS, str(exc), exc.retry_after
            ) from None
    return Response(image, media_type="image/png", headers={"Cache-Control": "no-store"})
