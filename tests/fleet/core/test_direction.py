"""Direction choice (cw/ccw) by closed-loop rollouts of the batch simulator."""

from __future__ import annotations

import itertools
import math

import pytest

from fleet.core.direction import SCREEN_DT, Mover, Scene, choose_directions, evaluate
from fleet.core.params import Tolerance
from fleet.core.types import LAWS, Law
from fleet.paper.scenarios import SCENARIOS

TOL = Tolerance(position=0.1, heading=0.1)
SEP = 0.5
#: The scenes below were built around the paper's Table 1 gains (the service's defaults
#: before the yard tuning); they pin them so the search is tested, not the defaults.
TABLE_1 = dict(SCENARIOS["first"].gains)


def swap(
    n: int, radius: float, start_off: float, goal_off: float, laws: tuple[Law | None, ...] = ()
) -> Scene:
    """N robots on a circle, each parking at the antipodal point (heading offsets in rad)."""
    movers = []
    for i in range(n):
        a = 2 * math.pi * i / n
        law = laws[i] if laws else None
        movers.append(
            Mover(
                robot_id=f"r{i}",
                pose=(radius * math.cos(a), radius * math.sin(a), a + math.pi + start_off),
                goal=(-radius * math.cos(a), -radius * math.sin(a), a + math.pi + goal_off),
                gains=TABLE_1,
                tolerance=TOL,
                law=law,
            )
        )
    return Scene(movers=movers)


def test_two_robots_swapping_sides_get_a_safe_and_fastest_choice() -> None:
    scene = swap(2, 4.0, math.pi / 4, -math.pi / 4)
    outcomes = {laws: evaluate(scene, laws, SEP) for laws in itertools.product(LAWS, repeat=2)}
    assert any(not o.safe for o in outcomes.values()), "the scenario should have a bad choice"
    decision = choose_directions(scene, SEP)
    best = decision.best
    assert best.safe and best.done
    assert best.min_separation >= SEP
    assert best.key == min(o.key for o in outcomes.values())
    assert decision.evaluations == 4


def test_fixed_directions_are_respected() -> None:
    scene = swap(2, 4.0, math.pi / 4, -math.pi / 4)
    fixed = Mover(**{**scene.movers[0].__dict__, "law": "ccw", "auto": False})
    decision = choose_directions(Scene(movers=[fixed, scene.movers[1]]), SEP)
    assert decision.best.laws[0] == "ccw"


def test_robots_under_way_keep_their_law_when_it_is_safe() -> None:
    scene = swap(2, 4.0, math.pi / 4, -math.pi / 4, ("ccw", "ccw"))
    keep = evaluate(scene, ("ccw", "ccw"), SEP)
    faster = evaluate(scene, ("cw", "cw"), SEP)
    assert keep.safe and faster.key < keep.key  # switching would be faster, not safer
    assert choose_directions(scene, SEP).best.laws == ("ccw", "ccw")


def test_robots_under_way_switch_only_when_strictly_safer() -> None:
    scene = swap(2, 4.0, math.pi / 4, -math.pi / 4, ("ccw", "cw"))
    assert not evaluate(scene, ("ccw", "cw"), SEP).safe
    best = choose_directions(scene, SEP).best
    assert best.laws != ("ccw", "cw") and best.safe


@pytest.mark.parametrize("n", [8])
def test_many_robots_use_a_bounded_local_search(n: int) -> None:
    scene = swap(n, 6.0, -math.pi / 4, math.pi / 4)
    decision = choose_directions(scene, SEP, exhaustive_limit=4, budget=6)
    assert decision.evaluations <= 2 + 6 + 1
    assert decision.best.safe and decision.best.done


def test_standing_robots_are_obstacles() -> None:
    mover = Mover("r0", (-3.0, 0.0, 0.0), (3.0, 0.0, 0.0), TABLE_1, TOL)
    free = evaluate(Scene(movers=[mover]), ("ccw",), SEP)
    blocked = evaluate(Scene(movers=[mover], standing=[(0.0, 0.0)]), ("ccw",), SEP)
    assert math.isinf(free.min_separation)
    assert blocked.min_separation < 1.0  # the rollout knows the parked robot is there


def test_yard_seed_2_gets_a_choice_whose_whole_rollout_keeps_the_separation() -> None:
    """The bench's random yard, seed 2 (10 robots), where ``auto`` used to collide: the
    rollouts at 0.05 s over 60 s judged a prefix of a ~80 s run with a coarse step."""
    from fleet.bench.fleet import random_yard_scenario
    from fleet.core.assignment import TaskSpec, optimal_assignment, predicted_times
    from fleet.core.params import RobotProfile

    yard = random_yard_scenario(10, 2)
    specs = [TaskSpec(g, LAWS, TABLE_1, yard.tolerance) for g in yard.goals]
    cost = predicted_times(yard.starts, specs, RobotProfile())
    movers = [
        Mover(f"b{i}", yard.starts[i], yard.goals[j], TABLE_1, yard.tolerance)
        for i, j in optimal_assignment(cost)
    ]
    scene = Scene(movers=movers)
    old = evaluate(scene, ("ccw",) * len(movers), SEP, dt=0.05, horizon=60.0)
    assert not old.done  # the old horizon cut the run short

    decision = choose_directions(scene, SEP)
    best = decision.best
    assert best.safe and best.done and best.makespan < decision.horizon
    assert decision.horizon > 60.0
    # the chosen laws, rolled out at the agents' 50 Hz over a horizon well past the arrivals
    check = evaluate(scene, best.laws, SEP, dt=0.02, horizon=300.0)
    assert check.done and check.min_separation >= SEP


@pytest.mark.parametrize("n", [2, 4, 8])
def test_screened_choice_is_verified_safe_at_the_agents_step(n: int) -> None:
    """Screening at 0.05 s, then verifying at 0.02 s: the chosen laws are safe when rolled
    out again at 0.02 s, and as fast as the search at 0.02 s alone."""
    scene = swap(n, 6.0, -math.pi / 4, math.pi / 4)
    screened = choose_directions(scene, SEP, screen_dt=SCREEN_DT)
    assert any("verified" in s for s in screened.searched)
    check = evaluate(scene, screened.best.laws, SEP, dt=0.02, horizon=300.0)
    assert check.safe and check.done and check.min_separation >= SEP
    fine = choose_directions(scene, SEP)
    assert screened.best.makespan <= fine.best.makespan + 0.5
