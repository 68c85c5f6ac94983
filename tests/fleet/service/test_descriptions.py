"""Robot descriptions in the roster and the service (in-memory bus, fake clock)."""

from __future__ import annotations

import pytest

from fleet.core.params import RobotProfile
from fleet.core.tasks import TaskConflict, TaskStatus
from fleet.core.wire import Pose, RobotDescription, RobotMode, RobotState
from fleet.service.roster import Roster
from tests.fleet.service.conftest import Fleet, ScriptedPlanner, assign_queued, req

SLOW = RobotProfile(wheel_radius=0.036, half_axle=0.117, max_wheel_speed=8.5, radius=0.17)


def state(rid: str, x: float = 0.0) -> RobotState:
    return RobotState(robot_id=rid, seq=1, stamp=0.0, pose=Pose(x=x, y=0.0), mode=RobotMode.IDLE)


def test_the_roster_keeps_one_description_per_robot_and_forgets_it_with_the_robot() -> None:
    roster = Roster()
    host = RobotProfile()
    roster.update(state("r1"), now=0.0, wall=0.0)
    assert roster.profile_of("r1", host) == host
    view = roster.view("r1")
    assert view is not None and not view.described and view.radius == pytest.approx(0.2)
    first = RobotDescription.of("r1", SLOW, model="TurtleBot 4")
    _, changed = roster.describe(first)
    assert changed
    _, changed = roster.describe(first)
    assert not changed  # a repeat (the put and the query's answer) changes nothing
    view = roster.view("r1")
    assert view is not None and view.described and view.model == "TurtleBot 4"
    assert view.radius == pytest.approx(0.17) and view.max_speed == pytest.approx(0.306)
    assert roster.profile_of("r1", host) == SLOW
    newer = RobotDescription.of("r1", SLOW, may_reverse=False)
    _, changed = roster.describe(newer)
    rec = roster.record("r1")
    assert changed and rec is not None and rec.description == newer  # replaced, not added
    roster.remove("r1")
    assert roster.profile_of("r1", host) == host and roster.record("r1") is None


def test_the_planner_gets_each_robots_own_profile_and_the_host_one_for_the_rest() -> None:
    planner = ScriptedPlanner(assign_queued())
    fleet = Fleet(planner=planner)
    try:
        fleet.join("slow", 0.0, 0.0)
        fleet.join("old", 0.0, 4.0)
        fleet.bus.deliver_description(RobotDescription.of("slow", SLOW))
        fleet.service.submit(req(3.0, 0.0, robot="slow"))
        fleet.service.tick()
        robots = {r.robot_id: r for r in planner.snapshots[-1].robots}
        assert robots["slow"].profile == SLOW
        assert robots["old"].profile is None  # planned with the snapshot's (host) profile
        assert planner.snapshots[-1].profile == fleet.settings.profile
        assert fleet.service.robot("old").described is False
    finally:
        fleet.service.close()


def test_a_robot_that_may_not_reverse_is_refused_by_name_and_skipped_by_auto_assignment() -> None:
    fleet = Fleet()
    try:
        fleet.join("fwd", 0.0, 0.0)  # nearer the goal ...
        fleet.join("any", -6.0, 0.0)
        fleet.bus.deliver_description(RobotDescription.of("fwd", RobotProfile(), may_reverse=False))
        with pytest.raises(TaskConflict, match="may not reverse"):
            fleet.service.submit(req(3.0, 0.0, robot="fwd"))
        task = fleet.service.submit(req(3.0, 0.0))
        fleet.service.tick()
        got = fleet.service.task(task.id)
        assert got.status == TaskStatus.ASSIGNED and got.robot_id == "any"  # ... but skipped
        assert fleet.parks("fwd") == []
    finally:
        fleet.service.close()


def test_auto_assignment_prices_each_robot_with_its_own_speed() -> None:
    fleet = Fleet()
    try:
        fleet.join("slow", 1.0, 0.0)  # 2 m behind the goal: 2.4 s at 1 m/s, 6.5 s at its own
        fleet.join("fast", 5.5, 0.0)  # 2.5 m ahead, backing in: 2.9 s at 1 m/s
        fleet.bus.deliver_description(RobotDescription.of("slow", SLOW))
        task = fleet.service.submit(req(3.0, 0.0))
        fleet.service.tick()
        assert fleet.service.task(task.id).robot_id == "fast"
    finally:
        fleet.service.close()
