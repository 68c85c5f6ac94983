"""``parkfleet plot`` and the plotting function write real PNG figures."""

from __future__ import annotations

import math
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.patches import Polygon

from fleet.cli.main import main
from fleet.drawing import plot_trajectory, save_figure, triangle
from fleet.paper.plotting import plot_case, plot_compare, plot_pareto

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) in pixels from the IHDR chunk, after checking the signature."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, "not a PNG file"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return int(width), int(height)


def test_cli_writes_a_png_and_prints_its_path(tmp_path: Path) -> None:
    out = tmp_path / "case-I-cw.png"
    # No MPLBACKEND: the command must pick Agg itself and never open a window.
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    env["PYTHONWARNINGS"] = "error"
    proc = subprocess.run(
        [sys.executable, "-m", "fleet.cli", "plot", "I", "--law", "cw", "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert proc.stdout.strip() == str(out)
    width, height = png_size(out)
    assert 500 <= width <= 2000 and width < height <= 3000  # three panels stacked


@pytest.mark.parametrize(
    "argv", [["plot", "IV", "-o", "x.png"], ["plot", "I", "--law", "up", "-o", "x.png"]]
)
def test_cli_rejects_unknown_case_or_law(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def _straight_run(steps: int = 100) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(steps + 1) * 0.01
    poses = np.column_stack([t, 0.5 * t, np.full_like(t, math.atan2(0.5, 1.0))])
    controls = np.column_stack([np.full(steps, math.hypot(1.0, 0.5)), np.zeros(steps)])
    errors = np.column_stack([1.0 - t[:-1], np.zeros(steps), np.zeros(steps)])
    return poses, controls, errors


def test_plot_trajectory_draws_path_triangles_controls_and_errors(tmp_path: Path) -> None:
    poses, controls, errors = _straight_run()
    fig = plot_trajectory(poses, controls, 0.01, (1.0, 0.5, 0.0), "straight", errors=errors)
    path_ax, control_ax, error_ax = fig.axes[:3]
    assert len(fig.axes) == 3
    np.testing.assert_array_equal(path_ax.lines[0].get_xydata(), poses[:, :2])
    triangles = [p for p in path_ax.patches if isinstance(p, Polygon)]
    assert len(triangles) >= 10  # orientation marks along the path, plus start and goal
    assert len(control_ax.lines) == 2 and len(error_ax.lines) == 3
    np.testing.assert_allclose(
        np.asarray(control_ax.lines[0].get_xdata(), float), np.arange(100) * 0.01
    )
    width, height = png_size(save_figure(fig, tmp_path / "straight.png"))
    assert width > 300 and height > width


def test_errors_are_optional_for_live_recordings(tmp_path: Path) -> None:
    poses, controls, _ = _straight_run()
    fig = plot_trajectory(poses, controls, 0.01, (1.0, 0.5, 0.0), "live task", every=10)
    assert len(fig.axes) == 2
    assert png_size(save_figure(fig, tmp_path / "live.png"))[0] > 300


def test_triangle_points_along_the_heading() -> None:
    tri = triangle(np.array([1.0, 2.0, math.pi / 2]), 0.1)
    nose = tri[0]
    np.testing.assert_allclose(nose, [1.0, 2.1], atol=1e-12)
    assert (tri[1:, 1] < 2.0).all()  # the base lies behind the centre
    np.testing.assert_allclose(np.linalg.norm(tri[1] - nose), np.linalg.norm(tri[2] - nose))


def test_plot_case_titles_the_law_and_arrival_time() -> None:
    fig = plot_case("parking", "cw")
    title = fig.get_suptitle()
    assert "Eq. (20)" in title and "t = 40.71 s" in title


@pytest.mark.parametrize(
    ("controls_shape", "errors_shape", "match"),
    [((99, 2), None, "controls"), ((100, 2), (100, 2), "errors")],
)
def test_mismatched_shapes_are_rejected(
    controls_shape: tuple[int, int], errors_shape: tuple[int, int] | None, match: str
) -> None:
    poses, _, _ = _straight_run()
    errors = None if errors_shape is None else np.zeros(errors_shape)
    with pytest.raises(ValueError, match=match):
        plot_trajectory(poses, np.zeros(controls_shape), 0.01, (0, 0, 0), "bad", errors=errors)


def test_compare_draws_every_controllers_path_on_one_figure(tmp_path: Path) -> None:
    out = tmp_path / "compare.png"
    assert main(["plot", "III", "--compare", "-o", str(out)]) == 0
    assert png_size(out)[0] > 300
    fig = plot_compare("III")
    (ax,) = fig.axes
    labels = [line.get_label() for line in ax.lines]
    names = ["(17) ccw", "(20) cw", "VFO", "FT", "Astolfi", "Park-Kuipers"]
    assert [label.split(":")[0] for label in labels] == names
    start = ax.lines[0].get_xydata()[0]
    for line in ax.lines:  # every path starts at the scenario's start
        np.testing.assert_allclose(line.get_xydata()[0], start)
        assert "tolerance not reached" not in str(line.get_label())


def test_pareto_plot_marks_the_front_the_best_and_the_papers_gains() -> None:
    from fleet.paper.tune import case_target, tune

    result = tune(case_target("I", "cw"), seed=3, popsize=4, generations=2)
    fig = plot_pareto(result)
    (ax,) = fig.axes
    labels = {c.get_label() for c in ax.collections} | {line.get_label() for line in ax.lines}
    assert {"candidates", "Pareto front", "best (weighted cost)", "paper's gains"} <= labels
    assert "tune I, law cw" in fig.get_suptitle()
