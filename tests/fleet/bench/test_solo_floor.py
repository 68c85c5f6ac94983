"""What robots alone need: the single-robot floor of a scenario's zones (the corridor's
passage, one robot at a time; no zones, no floor) and the paper's law alone on the peers'
goals (never faster than the wheels allow, counted from each task's arrival, on the peers'
assignment)."""

from __future__ import annotations

import math

from fleet.bench.peers import assign_goals
from fleet.bench.scenarios import corridor, garage, random_yard, swap
from fleet.bench.solo_floor import law_alone, scenario_zones, zone_floor
from fleet.io.settings import load_settings


def test_the_corridors_passage_takes_each_robot_its_solo_time_one_after_the_other() -> None:
    settings = load_settings()
    scenario = corridor()
    (passage,) = scenario_zones(scenario, settings)
    assert passage.name == "passage-1" and passage.found
    floor = zone_floor(scenario, settings)
    top = settings.profile.max_speed  # 1 m/s: 8 m of corridor take each robot 8 s or more
    assert floor is not None and floor >= len(scenario.robots) * 8.0 / top
    one = zone_floor(scenario.model_copy(update={"robots": scenario.robots[:1]}), settings)
    assert one is not None and 0 < one < floor


def test_without_zones_there_is_no_floor() -> None:
    settings = load_settings()
    assert zone_floor(garage(), settings) is None
    off = settings.model_copy(update={"narrow_passages": False})
    assert zone_floor(corridor(), off) is None


def test_the_law_alone_is_no_faster_than_the_wheels_and_counts_from_each_arrival() -> None:
    settings = load_settings()
    scenario = swap(4, "right")
    alone = law_alone(scenario, settings)
    top = settings.profile.max_speed
    longest = max(math.dist(r.start[:2], r.goal[:2]) for r in scenario.robots)
    assert alone is not None and alone >= longest / top
    later = scenario.model_copy(
        update={"robots": [r.model_copy(update={"arrival_s": 10.0}) for r in scenario.robots]}
    )
    assert law_alone(later, settings) == alone + 10.0


def test_unnamed_goals_go_to_the_robots_the_peers_give_them() -> None:
    """A yard whose goals the fleet assigns: the estimate is that of the same robots named
    to the goals the peers' assignment gives them."""
    settings = load_settings()
    scenario = random_yard(10, 1)
    owner = assign_goals(scenario)
    named = scenario.model_copy(
        update={
            "named": True,
            "robots": [
                r.model_copy(update={"goal": scenario.robots[owner.index(i)].goal})
                for i, r in enumerate(scenario.robots)
            ],
        }
    )
    assert owner != list(range(10))
    assert law_alone(scenario, settings) == law_alone(named, settings)
