"""One picture per (scenario, policy) run: paths, oriented robots, collisions, a metrics line.

Drawn with matplotlib's object-oriented API on the Agg canvas (no window, no pyplot state).
Each robot's true path (subsampled) in its own colour, a hollow triangle at its start, a
filled one where it ended and a dashed outline at its goal (triangles as in the paper's
figures, nose along theta); static obstacles as grey bodies inside dashed influence zones;
a red circle where two robots touched (first instant of each contact), an orange square
where a robot was found deadlocked; the metrics line of the run as the title.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from fleet.bench.metrics import RunResult
from fleet.bench.scenarios import Scenario
from fleet.drawing import save_figure, triangle


def plot_run(scenario: Scenario, result: RunResult, title: str, path: str | Path) -> Path:
    """Write the PNG of one run to ``path`` (parent folders created); returns the path."""
    fig = Figure(figsize=(8.0, 8.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, linewidth=0.3)
    for o in scenario.obstacles:
        ax.add_patch(Circle((o.x, o.y), o.radius, fill=False, linestyle=":", color="0.6"))
        ax.add_patch(Circle((o.x, o.y), max(o.body, 0.02), color="0.35"))
    for wall in scenario.walls:
        points = [*wall.points, wall.points[0]] if wall.closed else wall.points
        xs, ys = zip(*points, strict=True)
        # The wall's body: a line as thick as the wall (points: 72 per inch, 8 in per figure).
        ax.plot(xs, ys, color="0.35", solid_capstyle="round", linewidth=2.0, zorder=1)
    n = result.paths.shape[1] if result.paths.size else len(scenario.robots)
    colours = [f"C{k % 10}" for k in range(n)]
    size = 0.35
    for r in range(n):
        colour = colours[r]
        if result.paths.size:
            ax.plot(result.paths[:, r, 0], result.paths[:, r, 1], color=colour, linewidth=0.9)
        if not np.isnan(result.starts[r, 0]):
            tri = triangle(result.starts[r], size)
            ax.add_patch(Polygon(tri, closed=True, facecolor="none", edgecolor=colour))
        if not np.isnan(result.final[r, 0]):
            ax.add_patch(Polygon(triangle(result.final[r], size), closed=True, color=colour))
        if not np.isnan(result.goals[r, 0]):
            goal = triangle(result.goals[r], 1.3 * size)
            ax.add_patch(
                Polygon(goal, closed=True, facecolor="none", edgecolor=colour, linestyle="--")
            )
    for event in result.collisions:
        ax.add_patch(Circle((event.x, event.y), 0.3, fill=False, color="red", linewidth=1.5))
    for event in result.deadlocks:
        ax.plot(event.x, event.y, marker="s", markersize=9, fillstyle="none", color="orange")
    ax.margins(0.05)
    ax.autoscale_view()
    ax.set_title(title, fontsize=9)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, path)
