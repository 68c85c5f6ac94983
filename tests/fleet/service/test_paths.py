"""Recorded paths: a ring per task that downsamples when full, and a global cap."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.service.paths import PathRecorder, PathSample


def sample(k: int) -> PathSample:
    return (float(k), float(k), 0.0, 0.0, 0.0, 0.0)


def test_a_full_path_is_downsampled_but_spans_the_whole_task() -> None:
    rec = PathRecorder(per_task=10, total=100)
    rec.start("t")
    for k in range(1000):
        rec.record("t", sample(k))
    path = rec.get("t")
    assert path is not None
    assert len(path) <= 10 + 1  # the ring, plus the latest offer
    times = [p[0] for p in path]
    assert times == sorted(times)
    assert times[0] == 0.0 and times[-1] == 999.0  # first and latest sample kept
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert max(gaps) <= 2 * 1000 / 10  # evenly thinned, no hole
    assert rec.samples <= 10


def test_the_finished_path_ends_at_the_last_pose() -> None:
    rec = PathRecorder(per_task=4, total=100)
    rec.start("t")
    for k in range(7):
        rec.record("t", sample(k))
    rec.finish("t")
    path = rec.get("t")
    assert path is not None and path[-1] == sample(6)
    rec.record("t", sample(99))  # a finished path takes no more samples
    assert rec.get("t") == path


def test_over_the_global_cap_finished_paths_go_first_then_running_ones_thin() -> None:
    rec = PathRecorder(per_task=50, total=100)
    for name in ("old", "new"):
        rec.start(name)
        for k in range(40):
            rec.record(name, sample(k))
        rec.finish(name)
    assert "old" in rec and "new" in rec and rec.samples == 80
    rec.start("run")
    for k in range(40):
        rec.record("run", sample(k))
    assert "old" not in rec and "new" in rec  # the oldest finished path went
    assert rec.samples <= 100
    rec.start("run2")
    for k in range(200):
        rec.record("run2", sample(k))
    assert "new" not in rec  # every finished path went before a running one shrinks
    assert rec.samples <= 100
    assert "run" in rec and "run2" in rec  # running paths are thinned, never dropped


def test_finished_paths_are_bounded_in_number() -> None:
    rec = PathRecorder(per_task=4, total=1000, max_finished=3)
    for k in range(10):
        rec.start(f"t{k}")
        rec.record(f"t{k}", sample(k))
        rec.finish(f"t{k}")
    assert len(rec) == 3 and [f"t{k}" in rec for k in (6, 7, 8, 9)] == [False, True, True, True]


def test_bad_bounds_are_refused() -> None:
    with pytest.raises(ValueError):
        PathRecorder(per_task=1)
    with pytest.raises(ValueError):
        PathRecorder(per_task=10, total=5)


@settings(max_examples=60, deadline=None)
@given(
    per_task=st.integers(2, 20),
    extra=st.integers(0, 40),
    ops=st.lists(st.tuples(st.sampled_from("srf"), st.integers(0, 5)), max_size=300),
)
def test_the_bounds_always_hold(per_task: int, extra: int, ops: list[tuple[str, int]]) -> None:
    total = per_task + extra
    rec = PathRecorder(per_task=per_task, total=total, max_finished=3)
    offered: dict[str, int] = {}
    for op, k in ops:
        name = f"t{k}"
        if op == "s":
            rec.start(name)
            offered[name] = 0
        elif op == "r":
            rec.record(name, sample(offered.get(name, 0)))
            if name in offered:
                offered[name] += 1
        else:
            rec.finish(name)
        assert rec.samples <= total
        assert rec.samples == sum(len(rec.get(n) or []) for n in offered if n in rec) - sum(
            1 for n in offered if n in rec and _has_tail(rec, n)
        )
        for n in offered:
            path = rec.get(n)
            if path is not None:
                assert len(path) <= per_task + 1
                times = [p[0] for p in path]
                assert times == sorted(times)


def _has_tail(rec: PathRecorder, name: str) -> bool:
    path = rec._running.get(name)
    return path is not None and path.tail is not None
