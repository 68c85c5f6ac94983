"""bench failover's bookkeeping: what counts as a stale (deposed) message and as obeying it;
where the task stream sends robots."""

from __future__ import annotations

import itertools
import math

from support import FakePayload, FakeSample, park

from fleet.bench.failover import Wire, _bays
from fleet.core.wire import Pose, RobotState, encode


def _sample(message: object) -> FakeSample:
    return FakeSample("k", FakePayload(encode(message)))  # type: ignore[arg-type]


def _state(task: str, revision: int = 0) -> FakeSample:
    state = RobotState(robot_id="r1", seq=1, stamp=0.0, pose=Pose(x=0, y=0), task_id=task,
                       revision=revision)  # fmt: skip
    return _sample(state)


def test_a_lower_term_after_a_higher_one_is_stale_and_running_only_it_is_obeying_it() -> None:
    wire = Wire()
    wire.on_assignment(_sample(park("r1", "t1", term=2)))
    wire.on_assignment(_sample(park("r1", "t1", term=2, revision=1)))
    wire.on_assignment(_sample(park("r1", "t9", term=1)))  # the deposed leader's
    wire.on_assignment(_sample(park("r1", "t1", term=1, revision=1)))  # also sent by term 2
    assert wire.stale_sent == 2 and wire.term_after(1) == wire.first_seen[2]
    wire.on_state(_state("t1", 1))
    assert wire.obeyed == set()  # the new leader sent that one too
    wire.on_state(_state("t9"))
    assert wire.obeyed == {"r1"}
    assert wire.robots_of["t1"] == {"r1"} and wire.decoder.dropped_total == 0


def test_the_stream_goals_lie_in_the_yard_apart_and_off_the_spawn_grid() -> None:
    for robots in (10, 20, 50):
        bays = _bays(robots)
        half = 1.5 * (math.ceil(math.sqrt(robots)) - 1) / 2  # the spawn grid's half width
        assert len(bays) > robots  # a free bay for every robot at least
        assert all(abs(x) <= 9 and abs(y) <= 9 and max(abs(x), abs(y)) > half for x, y in bays)
        assert min(math.dist(a, b) for a, b in itertools.combinations(bays, 2)) >= 1.5 - 1e-9
