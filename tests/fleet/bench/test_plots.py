"""Run pictures: one PNG per run, collisions marked in red."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.image import imread

from fleet.bench.metrics import RunMetrics, RunResult
from fleet.bench.plots import plot_run
from fleet.bench.scenarios import case_iii_crossing
from fleet.core.wire import Obstacle
from fleet.io.trace import TraceChunk

MODES = ("idle", "driving", "arrived")


def _result(meet: bool) -> RunResult:
    s = np.linspace(0.0, 1.0, 200)[:, None]
    a = np.column_stack([-2 + 4 * s, 0 * s, 0 * s])
    b = np.column_stack([0 * s, (-2 if meet else -3) + 4 * s, 0 * s + math.pi / 2])
    poses = np.stack([a, b], axis=1)
    m = RunMetrics([0.2, 0.2], poses[-1], [Obstacle(x=0.0, y=3.0, body=0.2)], MODES)
    m.add(TraceChunk(np.arange(200) * 0.02, poses, np.ones((200, 2), dtype=np.uint8)))
    return m.result()


def _red_pixels(path: Path) -> int:
    image = imread(path)
    red = (image[..., 0] > 0.9) & (image[..., 1] < 0.2) & (image[..., 2] < 0.2)
    return int(red.sum())


def test_a_png_per_run_with_its_collisions_in_red(tmp_path: Path) -> None:
    scenario = case_iii_crossing()
    hit = plot_run(scenario, _result(True), "meet | title", tmp_path / "a" / "meet.png")
    miss = plot_run(scenario, _result(False), "miss | title", tmp_path / "miss.png")
    assert hit.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert imread(hit).shape[:2] == (800, 800)
    assert _red_pixels(hit) > 50 and _red_pixels(miss) == 0
