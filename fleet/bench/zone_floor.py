"""The single-robot floor of a scenario's zones: how long robots one at a time need in them.

For every single-robot zone of a scenario -- its declared zones and the narrow passages its
walls and posts make (:mod:`fleet.core.planner.passages`, as the fleet service finds them)
-- each robot is predicted alone, from its start to its goal (robot k to goal k), on the
planner's own solo prediction (:mod:`fleet.core.planner.scene`: the compiled step, its
route, its fastest law), and the time its centre spends inside the zone is summed over the
robots. The largest sum over the zones is the floor a one-at-a-time zone puts under the
makespan: reported beside it (``FleetBenchRow.zone_solo_s``). A zone that allows convoys
(every passage found) can beat it: robots going the same way are in it together.
"""

from __future__ import annotations

import numpy as np

from fleet.bench.scenarios import Scenario
from fleet.core.planner import PlannerConfig, PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.planner.passages import narrow_passages
from fleet.core.planner.scene import build_fleet
from fleet.core.route import lane_shapes
from fleet.core.tasks import DEFAULT_GAINS, RobotStatus, TaskStatus
from fleet.core.zones import ZoneShape, declared
from fleet.io.settings import Settings


def scenario_zones(scenario: Scenario, settings: Settings) -> tuple[ZoneShape, ...]:
    """The scenario's single-robot zones as the fleet service holds them."""
    obstacles = tuple(scenario.static_obstacles())
    zones = declared(scenario.site())
    if not settings.narrow_passages or not obstacles:
        return zones
    radius = settings.profile.radius
    clearance = PlannerConfig().route_clearance(radius, settings.safety.contact_margin_m)
    return zones + narrow_passages(obstacles, clearance, radius)


def zone_floor(scenario: Scenario, settings: Settings) -> float | None:
    """The largest sum over robots of the time each, alone, spends in one zone [s]
    (module docstring); None without zones."""
    zones = scenario_zones(scenario, settings)
    if not zones:
        return None
    spent = np.zeros(len(zones))
    site = scenario.site()
    lanes = () if site is None else lane_shapes(site.lanes)
    gains = dict(DEFAULT_GAINS) | (scenario.law_gains or {})
    for k, spec in enumerate(scenario.robots):
        snapshot = PlanningSnapshot(
            version=1,
            robots=(RobotSnapshot("solo", spec.start, RobotStatus.IDLE, available=True),),
            tasks=(
                TaskSnapshot(
                    f"t{k}", spec.goal, "auto", gains, scenario.tolerance, TaskStatus.QUEUED, 0.0,
                    named_robot="solo",
                ),
            ),
            obstacles=tuple(scenario.static_obstacles()),
            profile=settings.profile,
            avoidance=settings.avoidance,
            safety=settings.safety,
            control_dt=1.0 / settings.control_rate_hz,
            lanes=lanes,
        )  # fmt: skip
        fleet = build_fleet(snapshot, [(snapshot.tasks[0], snapshot.robots[0])], PlannerConfig())
        law = int(np.argmin(np.where(fleet.movers.allowed[0], fleet.solo_time[0], np.inf)))
        times = fleet.solo_times
        period = float(times[1] - times[0]) if times.size > 1 else 0.0
        path = fleet.solo_xy[:, 0, law]
        arrived = fleet.solo_time[0, law]
        moving = times < arrived if np.isfinite(arrived) else np.ones(times.size, dtype=bool)
        for z, zone in enumerate(zones):
            inside = [zone.contains(float(x), float(y)) for x, y in path[moving]]
            spent[z] += period * sum(inside)
    return round(float(spent.max()), 1)


__all__ = ["scenario_zones", "zone_floor"]
