"""The ranking of candidate plans (:mod:`fleet.core.planner.cost`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet.core.planner.cost import Score
from fleet.core.planner.scene import Candidate


def score(held: int = 0, unfinished: int = 0, makespan: float = 10.0) -> Score:
    k = 3
    hold = np.arange(k) < held
    candidate = Candidate(np.zeros(k, dtype=np.int64), np.zeros(k), hold)
    return Score(
        candidate=candidate, shortfall=0.0, held=held, trapped=0, unfinished=unfinished,
        makespan=makespan, total=3 * makespan, changes=0, min_separation=1.0,
        arrival=np.full(k, makespan), separation=np.ones(k), pair_min=np.ones((k, k)),
        violations=(), penalty_s=0.0, stopped_at=makespan, estimate=makespan,
    )  # fmt: skip


def test_a_hold_wins_only_where_it_lets_more_robots_arrive_than_it_stops() -> None:
    jam = score(unfinished=2)  # everybody drives, two never arrive (their filters jam)
    one_waits = score(held=1, makespan=30.0)  # one holds, the other two arrive
    assert one_waits.key < jam.key
    lost = score(unfinished=1)  # a robot that arrives neither way drives
    assert lost.key < score(held=1).key
    assert score(makespan=50.0).key < score(held=1, makespan=20.0).key  # last resort


def test_an_unsafe_plan_ranks_after_every_safe_one() -> None:
    unsafe = dataclasses.replace(score(), shortfall=0.1)
    assert score(held=3, unfinished=0).key < unsafe.key
