"""The single-robot floor of a scenario's zones: the corridor's passage, one robot at a
time; no zones, no floor."""

from __future__ import annotations

from fleet.bench.scenarios import corridor, garage
from fleet.bench.zone_floor import scenario_zones, zone_floor
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
