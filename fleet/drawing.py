"""Drawing a robot's path in the style of the paper: oriented triangles, controls, errors.

Neutral ground below both :mod:`fleet.paper` (the paper's figures) and :mod:`api` (a task's
plot), and :mod:`fleet.bench` (a run's picture): it imports only :mod:`fleet.core` and
matplotlib, never the paper's simulations, baselines or optimiser. Pure of any window
system: figures are built with matplotlib's object-oriented API on the Agg canvas, so
nothing here touches ``pyplot`` global state or opens a window (threads may draw at once).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from fleet.core.types import Law

__all__ = [
    "DEFAULT_TRIANGLES",
    "LAW_EQUATION",
    "draw_path",
    "finish_map",
    "plot_trajectory",
    "save_figure",
    "triangle",
    "triangle_indices",
]

#: Number of triangles drawn along a path when the caller does not choose a spacing.
DEFAULT_TRIANGLES = 20

#: The paper's equation of each law, as figure titles name it.
LAW_EQUATION: dict[Law, str] = {"ccw": "Eq. (17)", "cw": "Eq. (20)"}


def triangle(pose: npt.NDArray[np.float64], size: float) -> npt.NDArray[np.float64]:
    """Vertices (3, 2) [m] of an isosceles triangle centred on ``pose``, nose along theta."""
    x, y, theta = (float(v) for v in pose)
    body = np.array([[size, 0.0], [-0.5 * size, 0.3 * size], [-0.5 * size, -0.3 * size]])
    c, s = math.cos(theta), math.sin(theta)
    rotation = np.array([[c, -s], [s, c]])
    return np.asarray(body @ rotation.T + np.array([x, y]), dtype=np.float64)


def triangle_indices(
    poses: npt.NDArray[np.float64], size: float, every: int | None
) -> npt.NDArray[np.intp]:
    """Steps at which to draw a triangle: every ``every`` steps, or evenly spread.

    The default spreads :data:`DEFAULT_TRIANGLES` evenly over travelled distance plus
    turning (one radian counts as one triangle length), so fast stretches, slow
    final approaches and turns on the spot all show.
    """
    if every is not None:
        return np.arange(0, poses.shape[0], every)
    moved = np.hypot(np.diff(poses[:, 0]), np.diff(poses[:, 1]))
    progress = np.concatenate([[0.0], np.cumsum(moved + size * np.abs(np.diff(poses[:, 2])))])
    targets = np.linspace(0.0, progress[-1], DEFAULT_TRIANGLES + 1)
    return np.unique(np.minimum(np.searchsorted(progress, targets), poses.shape[0] - 1))


def draw_path(
    ax: Axes,
    poses: npt.NDArray[np.float64],
    goal: npt.NDArray[np.float64],
    every: int | None,
) -> None:
    points = np.vstack([poses[:, :2], goal[None, :2]])
    span = float(max(np.ptp(points[:, 0]), np.ptp(points[:, 1]), 0.5))
    size = 0.035 * span
    ax.plot(poses[:, 0], poses[:, 1], color="tab:blue", linewidth=1.2, label="path")
    for k in triangle_indices(poses, size, every):
        ax.add_patch(
            Polygon(triangle(poses[k], size), closed=True, facecolor="none", edgecolor="k")
        )
    ax.add_patch(Polygon(triangle(poses[-1], size), closed=True, facecolor="tab:blue"))
    finish_map(ax, poses[0], goal, size)


def finish_map(
    ax: Axes, start: npt.NDArray[np.float64], goal: npt.NDArray[np.float64], size: float
) -> None:
    """Start and goal triangles, equal axes in metres, grid and legend."""
    ax.add_patch(Polygon(triangle(start, size), closed=True, facecolor="tab:green", label="start"))
    ax.add_patch(
        Polygon(
            triangle(goal, 1.3 * size),
            closed=True,
            facecolor="none",
            edgecolor="tab:red",
            linewidth=2.0,
            label="goal",
        )
    )
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")


def plot_trajectory(
    poses: npt.ArrayLike,
    controls: npt.ArrayLike,
    dt: float,
    goal: npt.ArrayLike,
    title: str,
    errors: npt.ArrayLike | None = None,
    every: int | None = None,
) -> Figure:
    """Figure of one robot's run: path, control signals and (optionally) posture errors.

    Parameters
    ----------
    poses : array_like, shape (T+1, 3)
        World-frame postures (x [m], y [m], theta [rad]) at t = k dt, k = 0..T.
    controls : array_like, shape (T, 2)
        Applied (u [m/s], omega [rad/s]) of step k.
    dt : float
        Step [s].
    goal : array_like, shape (3,)
        Goal posture in the world frame.
    title : str
        Figure title.
    errors : array_like, shape (T, 3), optional
        Pre-step posture errors (x_e, y_e, theta_e) of Eq. (5); the error panel is left out
        when None (a robot task recorded live may not carry them).
    every : int, optional
        Steps between two orientation triangles; by default about
        :data:`DEFAULT_TRIANGLES` are spread evenly along the path (distance and turning).

    Returns
    -------
    matplotlib.figure.Figure
        A figure attached to an Agg canvas (save it with ``savefig``).
    """
    p = np.asarray(poses, dtype=np.float64)
    u = np.asarray(controls, dtype=np.float64)
    g = np.asarray(goal, dtype=np.float64).reshape(-1)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 1:
        raise ValueError(f"poses must have shape (T+1, 3), got {p.shape}")
    steps = p.shape[0] - 1
    if u.shape != (steps, 2):
        raise ValueError(f"controls must have shape ({steps}, 2), got {u.shape}")
    if g.shape != (3,):
        raise ValueError(f"goal must have 3 components (x, y, theta), got {g.shape}")
    e = None if errors is None else np.asarray(errors, dtype=np.float64)
    if e is not None and e.shape != (steps, 3):
        raise ValueError(f"errors must have shape ({steps}, 3), got {e.shape}")
    if not dt > 0:
        raise ValueError("dt must be positive")
    if every is not None and every < 1:
        raise ValueError("every must be at least 1 step")

    rows = 3 if e is not None else 2
    fig = Figure(figsize=(7.0, 3.2 + 2.2 * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, height_ratios=[2.2] + [1.0] * (rows - 1))
    fig.suptitle(title)
    draw_path(axes[0], p, g, every)

    t = np.arange(steps) * dt
    ax_u = axes[1]
    ax_u.plot(t, u[:, 0], label="u [m/s]")
    ax_u.plot(t, u[:, 1], label="ω [rad/s]")
    ax_u.set_ylabel("controls")
    ax_u.legend(loc="best", fontsize="small")
    ax_u.grid(True, alpha=0.3)
    if e is not None:
        ax_e = axes[2]
        ax_e.plot(t, e[:, 0], label="$x_e$ [m]")
        ax_e.plot(t, e[:, 1], label="$y_e$ [m]")
        ax_e.plot(t, e[:, 2], label="$θ_e$ [rad]")
        ax_e.set_ylabel("errors")
        ax_e.legend(loc="best", fontsize="small")
        ax_e.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    return fig


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = 100) -> Path:
    """Write ``fig`` as PNG to ``path`` and return the path."""
    out = Path(path)
    fig.savefig(out, dpi=dpi, format="png")
    return out
