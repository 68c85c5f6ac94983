"""The paper's figures: one scenario under a law, every controller on one map, Pareto fronts.

Drawn with :mod:`fleet.drawing` (paths with oriented triangles, controls and errors; the
Agg canvas, no window); this module adds what needs the paper's simulations, baselines and
tuning. ``plot_trajectory`` and ``save_figure`` are re-exported from there.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from fleet.core.simulate import PAPER_DT, SimResult
from fleet.core.types import LAWS, Law
from fleet.drawing import LAW_EQUATION, finish_map, plot_trajectory, save_figure
from fleet.paper.baselines import paper_baselines
from fleet.paper.reproduce import LAW_LABELS, run_baseline, run_scenario
from fleet.paper.scenarios import SCENARIOS, CaseName
from fleet.paper.tune import TuneResult, pareto_front

__all__ = ["plot_case", "plot_compare", "plot_pareto", "plot_trajectory", "save_figure"]


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
        f"{scenario.title}\nlaw {law}, {LAW_EQUATION[law]}; {status}",
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
        f"tune {target.name}, law {target.law} ({LAW_EQUATION[target.law]}): "
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
    finish_map(ax, np.asarray(scenario.start), np.asarray(scenario.goal), 0.03 * span)
    fig.suptitle(f"{scenario.title}: every controller")
    return fig
