"""Each robot planned with its own profile (``RobotSnapshot.profile``)."""

from __future__ import annotations

import dataclasses

from planning import scene

from fleet.core.params import RobotProfile
from fleet.core.planner import plan

SLOW = RobotProfile(wheel_radius=0.036, half_axle=0.117, max_wheel_speed=8.5, radius=0.17)


def test_a_slow_robots_predicted_arrival_uses_its_own_speed() -> None:
    base = scene([(0.0, 0.0, 0.0), (0.0, 4.0, 0.0)], [(4.0, 0.0, 0.0), (4.0, 4.0, 0.0)])
    slow = dataclasses.replace(base.robots[0], profile=SLOW)
    mixed = dataclasses.replace(base, robots=(slow, base.robots[1]))
    same = {d.robot_id: d.predicted_arrival_s for d in plan(base).decisions}
    arrival = {d.robot_id: d.predicted_arrival_s for d in plan(mixed).decisions}
    assert same["r0"] is not None and arrival["r0"] is not None and arrival["r1"] is not None
    assert arrival["r0"] > 2.5 * arrival["r1"]  # 0.306 m/s against 1 m/s
    assert arrival["r0"] > 3.9 / SLOW.max_speed  # 4 m less the 0.1 m tolerance
    assert same["r0"] < 1.5 * arrival["r1"]  # with the host profile it was as fast as r1
