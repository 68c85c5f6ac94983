"""What robots alone already need: the floor single-robot zones put under a makespan, and
the makespan of the paper's law with every robot alone.

Both predict each robot alone, on the planner's own solo prediction
(:mod:`fleet.core.planner.scene`: the compiled step on a perfect robot, its route, its
fastest law), and are reported beside the makespan of every run
(:class:`~fleet.bench.fleet.FleetBenchRow`):

* :func:`zone_floor` (``zone_solo_s``): for every single-robot zone of a scenario -- its
  declared zones and the narrow passages its walls and posts make
  (:mod:`fleet.core.planner.passages`, as the fleet service finds them) -- robot k from its
  start to goal k, the time its centre spends inside the zone, summed over the robots. The
  largest sum over the zones is the floor a one-at-a-time zone puts under the makespan. A
  zone that allows convoys (every passage found) can beat it: robots going the same way are
  in it together.
* :func:`law_alone` (``law_solo_s``): the makespan if no robot ever met another -- every
  task at its arrival time plus its robot's solo time under the paper's faster law, on the
  peers' assignment (:func:`fleet.bench.peers.assign_goals`: named tasks to their robot,
  else straight-line optimal per arrival group), straight to the goal or along the site's
  route (no open approach point, :class:`~fleet.core.planner.PlannerConfig`: the fleet's
  own robots can beat it by those). It holds the laws' own convergence
  (u = kx x_e slows down towards the goal, the heading is corrected on the way) and none
  of the fleet's interactions: the time the paper's law itself needs on the goals the
  peers drive to. It is an estimate, not a bound: ``auto`` may assign other goals (a
  random yard of 10: 12.4 s against 15.0 alone), and a peer's repulsion can push a robot
  onto a better way than its law finds alone (case III with four robots: 18.2 s against
  29.8). Set against the fastest peer's makespan it shows how much of the gap is the law.
"""

from __future__ import annotations

import numpy as np

from fleet.bench.peers import assign_goals
from fleet.bench.scenarios import Scenario
from fleet.core.planner import PlannerConfig, PlanningSnapshot, RobotSnapshot, TaskSnapshot
from fleet.core.planner.scene import Fleet, build_fleet
from fleet.core.route import lane_shapes
from fleet.core.tasks import DEFAULT_GAINS, RobotStatus, TaskStatus
from fleet.core.types import Posture
from fleet.core.zones import ZoneShape
from fleet.io.settings import Settings
from fleet.service.zones import fleet_zones


def scenario_zones(scenario: Scenario, settings: Settings) -> tuple[ZoneShape, ...]:
    """The scenario's single-robot zones as the fleet service holds them."""
    site = scenario.site()
    return fleet_zones(
        settings if site is None else settings.with_site(site), scenario.static_obstacles()
    )


def _solo(
    scenario: Scenario, settings: Settings, start: Posture, goal: Posture
) -> tuple[Fleet, int]:
    """The planner's prediction of one robot alone from ``start`` to ``goal`` and the index
    of its fastest allowed law."""
    site = scenario.site()
    snapshot = PlanningSnapshot(
        version=1,
        robots=(RobotSnapshot("solo", start, RobotStatus.IDLE, available=True),),
        tasks=(
            TaskSnapshot(
                "solo-task", goal, "auto", dict(DEFAULT_GAINS) | (scenario.law_gains or {}),
                scenario.tolerance, TaskStatus.QUEUED, 0.0, named_robot="solo",
            ),
        ),
        obstacles=tuple(scenario.static_obstacles()),
        profile=settings.profile,
        avoidance=settings.avoidance,
        safety=settings.safety,
        control_dt=1.0 / settings.control_rate_hz,
        lanes=() if site is None else lane_shapes(site.lanes),
    )  # fmt: skip
    straight = PlannerConfig(open_approach_m=())  # the law's own way (or the site's route)
    fleet = build_fleet(snapshot, [(snapshot.tasks[0], snapshot.robots[0])], straight)
    law = int(np.argmin(np.where(fleet.movers.allowed[0], fleet.solo_time[0], np.inf)))
    return fleet, law


def zone_floor(scenario: Scenario, settings: Settings) -> float | None:
    """The largest sum over robots of the time each, alone, spends in one zone [s]
    (module docstring); None without zones."""
    zones = scenario_zones(scenario, settings)
    if not zones:
        return None
    spent = np.zeros(len(zones))
    for spec in scenario.robots:
        fleet, law = _solo(scenario, settings, spec.start, spec.goal)
        times = fleet.solo_times
        period = float(times[1] - times[0]) if times.size > 1 else 0.0
        path = fleet.solo_xy[:, 0, law]
        arrived = fleet.solo_time[0, law]
        moving = times < arrived if np.isfinite(arrived) else np.ones(times.size, dtype=bool)
        for z, zone in enumerate(zones):
            inside = [zone.contains(float(x), float(y)) for x, y in path[moving]]
            spent[z] += period * sum(inside)
    return round(float(spent.max()), 1)


def law_alone(scenario: Scenario, settings: Settings) -> float | None:
    """The makespan [s] of every task driven by its robot alone under its faster law, from
    its arrival, on the peers' assignment (module docstring: an estimate, not a bound);
    None when a robot alone does not arrive within the planner's horizon."""
    owner = assign_goals(scenario)
    finish = 0.0
    for task, robot in enumerate(owner):
        spec = scenario.robots[task]
        fleet, law = _solo(scenario, settings, scenario.robots[robot].start, spec.goal)
        solo = float(fleet.solo_time[0, law])
        if not np.isfinite(solo):
            return None
        finish = max(finish, spec.arrival_s + solo)
    return round(finish, 1)


__all__ = ["law_alone", "scenario_zones", "zone_floor"]
