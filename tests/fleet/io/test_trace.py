"""Trace files: what a writer streams, a reader gives back, tick for tick."""

from __future__ import annotations

from contextlib import closing
from pathlib import Path

import numpy as np
import pytest

from fleet.io.trace import NO_MODE, TraceHeader, TraceWriter, read_header, read_trace

HEADER = TraceHeader(
    robots=("a", "b"), radii=(0.2, 0.3), period_s=0.02, modes=("idle", "driving", "arrived")
)


def _write(path: Path, ticks: int) -> np.ndarray:
    poses = np.random.default_rng(1).normal(size=(ticks, 2, 3))
    with closing(TraceWriter(path, HEADER)) as w:
        for k in range(ticks):
            w.write(k * 0.02, poses[k], [w.mode_code("driving"), w.mode_code(None)])
    return poses


def test_round_trip_in_chunks(tmp_path: Path) -> None:
    path = tmp_path / "t.trace"
    poses = _write(path, 25)
    assert read_header(path) == HEADER
    chunks = list(read_trace(path, chunk_ticks=10))
    assert [len(c.t) for c in chunks] == [10, 10, 5]
    np.testing.assert_array_equal(np.concatenate([c.poses for c in chunks]), poses)
    np.testing.assert_allclose(np.concatenate([c.t for c in chunks]), np.arange(25) * 0.02)
    modes = np.concatenate([c.modes for c in chunks])
    assert (modes[:, 0] == 1).all() and (modes[:, 1] == NO_MODE).all()


def test_a_partial_last_record_is_dropped(tmp_path: Path) -> None:
    path = tmp_path / "t.trace"
    _write(path, 3)
    data = path.read_bytes()
    path.write_bytes(data[:-5])  # a writer killed mid-record
    assert sum(len(c.t) for c in read_trace(path)) == 2


def test_bad_files_and_modes_are_named(tmp_path: Path) -> None:
    path = tmp_path / "t.trace"
    path.write_text('{"format": "other"}\n')
    with pytest.raises(ValueError, match="bad trace header"):
        read_header(path)
    with (
        closing(TraceWriter(tmp_path / "u.trace", HEADER)) as w,
        pytest.raises(ValueError, match="flying"),
    ):
        w.mode_code("flying")
    with pytest.raises(ValueError, match="one radius per robot"):
        TraceHeader(robots=("a",), radii=(), period_s=0.02, modes=())
