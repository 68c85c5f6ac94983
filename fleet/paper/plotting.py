"""Figures in the style of the paper: path with oriented triangles, controls and errors.

Pure of any window system: figures are built with matplotlib's object-oriented API on the
Agg canvas, so nothing here touches ``pyplot`` global state or opens a window.
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

from fleet.core.simulate import PAPER_DT, SimResult
from fleet.core.types import LAWS, Law
from fleet.paper.baselines import paper_baselines
from fleet.paper.reproduce import LAW_LABELS, run_baseline, run_scenario
from fleet.paper.scenarios import SCENARIOS, CaseName
from fleet.paper.tune import TuneResult, pareto_front

#: Number of triangles drawn along a path when the caller does not choose a spacing.
DEFAULT_TRIANGLES = 20

_LAW_EQUATION: dict[Law, str] = {"ccw": "Eq. (17)", "cw": "Eq. (20)"}


def _triangle(pose: npt.NDArray[np.float64], size: float) -> npt.NDArray[np.float64]:
    """Vertices (3, 2) [m] of an isosceles triangle centred on ``pose``, nose along theta."""
    x, y, theta = (float(v) for v in pose)
    body = np.array([[size, 0.0], [-0.5 * size, 0.3 * size], [-0.5 * size, -0.3 * size]])
    c, s = math.cos(theta), math.sin(theta)
    rotation = np.array([[c, -s], [s, c]])
    return np.asarray(body @ rotation.T + np.array([x, y]), dtype=np.float64)


def _triangle_indices(
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


def _draw_path(
    ax: Axes,
    poses: npt.NDArray[np.float64],
    goal: npt.NDArray[np.float64],
    every: int | None,
) -> None:
    points = np.vstack([poses[:, :2], goal[None, :2]])
    span = float(max(np.ptp(points[:, 0]), np.ptp(points[:, 1]), 0.5))
    size = 0.035 * span
    ax.plot(poses[:, 0], poses[:, 1], color="tab:blue", linewidth=1.2, label="path")
    for k in _triangle_indices(poses, size, every):
        ax.add_patch(
            Polygon(_triangle(poses[k], size), closed=True, facecolor="none", edgecolor="k")
        )
    ax.add_patch(Polygon(_triangle(poses[-1], size), closed=True, facecolor="tab:blue"))
    _finish_map(ax, poses[0], goal, size)


def _finish_map(
    ax: Axes, start: npt.NDArray[np.float64], goal: npt.NDArray[np.float64], size: float
) -> None:
    """Start and goal triangles, equal axes in metres, grid and legend."""
    ax.add_patch(Polygon(_triangle(start, size), closed=True, facecolor="tab:green", label="start"))
    ax.add_patch(
        Polygon(
            _triangle(goal, 1.3 * size),
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
    _draw_path(axes[0], p, g, every)

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


def plot_case(case: CaseName, law: Law, every: int | None = None) -> Figure:
    """Simulate one paper scenario with the paper's gains and plot it (dt = 0.01 s)."""
    scenario = SCENARIOS[case]
    result = run_scenario(scenario, law, record=True)
    traj = result.trajectory
    if traj is None:  # record=True always records; keeps the type checker honest
        raise RuntimeError("the simulator did not record a trajectory")
    status = f"t = {result.time[0]:.2f} s" if result.done[0] else "tolerance not reached"
    return plot_trajectory(
        traj.poses[:, 0, :],
        traj.controls[:, 0, :],
        PAPER_DT,
        scenario.goal,
        f"{scenario.title}\nlaw {law}, {_LAW_EQUATION[law]}; {status}",
        errors=traj.errors[:, 0, :],
        every=every,
    )


def plot_pareto(result: TuneResult) -> Figure:
    """Effort (Eq. 25) against distance of every candidate a search scored that arrived on
    every trip, its Pareto front, the best gains and the paper's (reference) gains."""
    target = result.target
    scores = result.evaluated
    ok = scores.done >= 1.0
    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    effort, distance = scores.effort[ok], scores.distance[ok]
    ax.scatter(effort, distance, s=6, color="0.7", label="candidates", zorder=1)
    front = pareto_front(effort, distance)
    if front.size:
        ax.plot(
            effort[front],
            distance[front],
            "-o",
            color="tab:blue",
            markersize=3,
            label="Pareto front",
            zorder=2,
        )
    marks = [(result.best_scores, "D", 60, "tab:green", "best (weighted cost)")]
    if result.reference_scores is not None:
        marks.append((result.reference_scores, "*", 160, "tab:red", "paper's gains"))
    for scored, marker, area, colour, label in marks:
        ax.scatter(
            [scored["effort"]],
            [scored["distance"]],
            marker=marker,
            s=area,
            color=colour,
            label=label,
            zorder=3,
        )
    # Frame the front and the marked gains; far-off candidates fall outside the view.
    e_seen = np.concatenate([effort[front], [m[0]["effort"] for m in marks]])
    d_seen = np.concatenate([distance[front], [m[0]["distance"] for m in marks]])
    for setter, seen in ((ax.set_xlim, e_seen), (ax.set_ylim, d_seen)):
        lo, hi = float(seen.min()), float(seen.max())
        setter(0.95 * lo, hi + 0.5 * (hi - lo) + 0.05 * hi)
    ax.set_xlabel("control effort, Eq. (25)")
    ax.set_ylabel("distance [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    fig.suptitle(
        f"tune {target.name}, law {target.law} ({_LAW_EQUATION[target.law]}): "
        f"{int(ok.sum())} of {ok.size} candidates arrived"
    )
    return fig


_COMPARE_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def plot_compare(case: CaseName) -> Figure:
    """Every controller's path on one paper scenario: laws (17), (20) with the paper's gains
    and the baselines (:func:`fleet.paper.baselines.paper_baselines`), dt = 0.01 s."""
    scenario = SCENARIOS[case]
    runs: list[tuple[str, SimResult]] = [
        (f"{LAW_LABELS[law]}", run_scenario(scenario, law, record=True)) for law in LAWS
    ]
    runs += [(c.name, run_baseline(scenario, c, record=True)) for c in paper_baselines(case)]
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    points = [np.asarray(scenario.start)[None, :2], np.asarray(scenario.goal)[None, :2]]
    for (name, result), colour in zip(runs, _COMPARE_COLOURS, strict=False):
        traj = result.trajectory
        if traj is None:  # record=True always records; keeps the type checker honest
            raise RuntimeError("the run did not record a trajectory")
        poses = traj.poses[:, 0, :]
        points.append(poses[:, :2])
        status = (
            f"{result.distance[0]:.2f} m, {result.time[0]:.2f} s"
            if result.done[0]
            else "tolerance not reached"
        )
        ax.plot(poses[:, 0], poses[:, 1], color=colour, linewidth=1.4, label=f"{name}: {status}")
    span = float(max(np.ptp(np.vstack(points), axis=0).max(), 0.5))
    _finish_map(ax, np.asarray(scenario.start), np.asarray(scenario.goal), 0.03 * span)
    fig.suptitle(f"{scenario.title}: every controller")
    return fig
