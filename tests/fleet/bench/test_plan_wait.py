"""A task's wait for the service, read from a trace: submission -> its robot leaves idle."""

from __future__ import annotations

import numpy as np

from fleet.bench.fleet import PlanWait
from fleet.io.trace import TraceChunk

MODES = ("idle", "driving", "arrived", "waiting")


def test_each_task_waits_from_its_submission_until_its_robot_is_assigned() -> None:
    t = np.arange(10) * 0.5
    modes = np.zeros((10, 2), dtype=np.uint8)
    modes[3:6, 0] = 3  # robot 0: a planned start delay at 1.5 s (assigned), then driving
    modes[6:8, 0] = 1
    modes[8:, 0] = 2  # parked at 4 s; its second task, submitted at 4 s, is never served
    waits = PlanWait()
    waits.expect(0, 0.5)
    waits.expect(1, 1.0)  # robot 1 stays idle: it never left
    waits.expect(0, 4.0)
    poses = np.zeros((10, 2, 3))
    for a in (0, 4):  # in two chunks
        waits.add(TraceChunk(t[a : a + 4] if a else t[:4], poses[:4], modes[a : a + 4]), MODES)
    waits.add(TraceChunk(t[8:], poses[:2], modes[8:]), MODES)
    assert waits.waits[0] == 1.0
    assert np.isnan(waits.waits[1]) and np.isnan(waits.waits[2])
