"""Orders "these go, those follow" for crowds whose goals are each other's starts."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.core.planner.search import crowd_orders, goal_cycles


@st.composite
def crowds(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Robots on distinct cells of a 1.5 m grid, each robot's goal the start of the robot a
    random permutation sends it to (jittered by up to 0.1 m), or a free cell."""
    n = draw(st.integers(2, 14))
    cells = draw(st.lists(st.integers(0, 63), min_size=2 * n, max_size=2 * n, unique=True))
    xy = np.array([(c % 8 * 1.5, c // 8 * 1.5) for c in cells], dtype=np.float64)
    start, free = xy[:n], xy[n:]
    perm = draw(st.permutations(range(n)))
    elsewhere = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    jitter = np.array(
        draw(st.lists(st.floats(-0.07, 0.07), min_size=2 * n, max_size=2 * n))
    ).reshape(n, 2)
    goal = np.where(np.array(elsewhere)[:, None], free, start[list(perm)]) + jitter
    successor = [-1 if elsewhere[a] else perm[a] for a in range(n)]
    return start, goal, successor


def _true_cycles(successor: list[int]) -> set[frozenset[int]]:
    out = set()
    for first in range(len(successor)):
        path, at = [first], successor[first]
        while at not in (-1, first) and at not in path:
            path.append(at)
            at = successor[at]
        if at == first:
            out.add(frozenset(path))
    return out


@settings(max_examples=200, deadline=None)
@given(crowds())
def test_the_cycles_are_those_of_the_goals_and_every_order_keeps_a_cycle_in_one_wave(
    crowd: tuple[np.ndarray, np.ndarray, list[int]],
) -> None:
    start, goal, successor = crowd
    cycles = goal_cycles(start, goal, within=0.5)
    assert {frozenset(c) for c in cycles} == _true_cycles(successor)
    for c in cycles:  # each in the order its robots lead to one another
        assert all(successor[a] == b for a, b in zip(c, c[1:] + c[:1], strict=True))
    orders = crowd_orders(start, goal, within=0.5, min_robots=6, max_waves=4)
    on_cycles = sum(map(len, cycles))
    assert bool(orders) == (len(cycles) >= 2 and on_cycles >= 6)
    for waves, order in enumerate(orders, start=2):
        assert set(order.tolist()) == set(range(waves))  # every wave has robots
        for c in cycles:
            assert len({order[i] for i in c}) == 1  # nobody waits on an earlier wave's goal
        off = [i for i in range(len(start)) if not any(i in c for c in cycles)]
        assert all(order[i] == 0 for i in off)  # robots on no cycle go at once


def test_a_swap_is_dealt_round_its_centre_so_that_neighbours_go_in_different_waves() -> None:
    """Sixteen robots on a circle, each to the antipodal point: eight pairs; in two waves
    every other pair round the circle waits, in four every fourth goes with it."""
    angle = 2 * np.pi * np.arange(16) / 16
    start = 6.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    goal = -start
    two, three, four = crowd_orders(start, goal, within=0.5)
    assert all(two[k] != two[(k + 1) % 16] for k in range(16))
    assert all(four[k] == four[k % 8] for k in range(16))  # a pair waits together
    assert sorted(four[:8].tolist()) == [0, 0, 1, 1, 2, 2, 3, 3]
    assert all(four[k] != four[(k + 1) % 16] for k in range(16))
    assert sorted(np.bincount(three.astype(int)).tolist()) == [4, 6, 6]
