"""The offline fleet drives the service's own ledger and reports the fleet bench's metrics."""

from __future__ import annotations

import math

import numpy as np

from fleet.bench.closed_loop import OfflineFleet, run_closed_loop
from fleet.bench.scenarios import ObstacleSpec, corridor, ring_round_posts, swap
from fleet.core.planner import Plan, TaskDecision, plan
from fleet.core.tasks import TaskStatus
from fleet.service.ledger import Outcome


def test_a_planned_swap_parks_every_task_through_the_ledger() -> None:
    scenario = swap(2, "left")
    fleet = OfflineFleet(scenario)
    assert fleet.submit_arrived() == 2
    work = fleet.snapshot()
    assert {t.status for t in work.snapshot.tasks} == {TaskStatus.QUEUED}
    fleet.apply(plan(work.snapshot), work)
    # the ledger assigned them and the robots acknowledged at once (no delivery delay)
    assert {t.status for t in fleet.tasks.values()} <= {TaskStatus.DRIVING, TaskStatus.WAITING}
    assert set(fleet.orders) == set(scenario.robot_ids)
    while not fleet.finished and fleet.t < 60.0:
        fleet.step(2.0)
    assert {t.status for t in fleet.tasks.values()} == {TaskStatus.SUCCEEDED}
    assert all(t.attempts == 1 for t in fleet.tasks.values())
    run = fleet.metrics()
    assert run.success_count() == 2 and run.collision_pairs == 0
    ratio = run.path_ratio()
    assert ratio is not None and ratio >= 1.0


def test_decisions_the_ledger_refuses_move_no_robot() -> None:
    fleet = OfflineFleet(swap(2, "right"))
    fleet.submit_arrived()
    work = fleet.snapshot()
    first = plan(work.snapshot)
    starts = [d for d in first.decisions if d.action == "assign" and not d.hold]
    assert starts
    unsafe = Plan(work.snapshot.version, tuple(starts), safe=False, min_separation_m=0.0)
    fleet.apply(unsafe, work)
    assert fleet.outcomes[Outcome.UNSAFE] == len(starts) and not fleet.orders
    fleet.apply(first, work)
    assert fleet.outcomes[Outcome.APPLIED] == len(first.decisions)
    fleet.apply(first, work)  # the same decisions again: the tasks are no longer queued
    assert fleet.outcomes[Outcome.STALE] == len(first.decisions)
    assert fleet.outcomes[Outcome.APPLIED] == len(first.decisions)


def test_a_fixed_law_that_blocks_fails_with_the_limit_as_makespan_and_no_path_ratio() -> None:
    """cw on a right-hand swap of 8: the robots jam at the centre and never park (the
    bench's own case where a simple rule breaks; with the default gains ccw gets through
    here, and up to 6 robots the safety filter's braking and sideways aim get either
    fixed law through); the planner gets them home."""
    scenario = swap(8, "right")
    blocked = run_closed_loop(scenario, "cw", time_limit_s=60.0)
    assert blocked.success_rate == 0.0
    assert blocked.makespan_s == 60.0
    assert math.isnan(blocked.path_ratio)  # over tasks that arrived: none did
    assert blocked.outcomes[Outcome.APPLIED] == 8  # all assigned, through the ledger
    planned = run_closed_loop(scenario, "auto", plan, time_limit_s=60.0)
    assert planned.success_rate == 1.0 and planned.collisions == 0
    assert planned.makespan_s < 60.0 and planned.path_ratio >= 1.0


def test_a_decision_names_its_robot_and_law_in_what_the_robot_is_told() -> None:
    fleet = OfflineFleet(swap(2, "left"))
    fleet.submit_arrived()
    work = fleet.snapshot()
    task = work.snapshot.tasks[0]
    robot = work.snapshot.robots[0].robot_id
    decision = TaskDecision(task.task_id, robot, "assign", "cw", task.revision, start_delay_s=1.0)
    fleet.apply(Plan(work.snapshot.version, (decision,), safe=True, min_separation_m=1.0), work)
    order = fleet.orders[robot].assignment
    assert (order.task_id, order.law, order.start_delay_s) == (task.task_id, "cw", 1.0)
    assert fleet.state(robot).mode == "waiting"  # its start delay runs in simulated time
    fleet.step(1.0)
    assert fleet.state(robot).mode in ("driving", "avoiding", "arrived")
    assert fleet.tasks[task.task_id].status is TaskStatus.DRIVING


def test_a_yard_beyond_the_service_s_runs_with_its_own_bounds() -> None:
    """200 robots at one per 10 m^2 do not fit the default 20 m yard: the scenario brings
    its yard and the offline fleet's settings (the service's) take it."""
    from fleet.bench.closed_loop import yard

    big = yard(200, 1)
    fleet = OfflineFleet(big)
    assert fleet.settings.yard == big.bounds and big.bounds[1] > 22.0
    assert fleet.submit_arrived() == 200


def test_the_offline_robots_drive_their_routes_via_points() -> None:
    # one robot whose straight way crosses a post: the plan routes it round the post, and
    # the offline robot must drive that route as the agent does (straight at its goal, its
    # filter and Eq. (27) hold it at the post for good: seed 3 parked nothing in 150 s)
    post = ObstacleSpec(x=0.0, y=0.0, radius=1.2, body=0.6)
    scenario = ring_round_posts(1, 5.0, [post], "ring-1", seed=3)
    fleet = OfflineFleet(scenario)
    fleet.submit_arrived()
    work = fleet.snapshot()
    fleet.apply(plan(work.snapshot), work)
    (order,) = fleet.orders.values()
    via = order.assignment.route
    assert via, "the plan routes the robot round the post"
    while not fleet.finished and fleet.t < 60.0:
        fleet.step(0.5)
    assert {t.status for t in fleet.tasks.values()} == {TaskStatus.SUCCEEDED}
    poses = np.concatenate([c.poses for c in fleet._chunks])[:, 0, :2]  # (T, 2)
    for x, y in via[:-1]:  # every via-point but the pre-bay point was driven through
        assert np.hypot(poses[:, 0] - x, poses[:, 1] - y).min() <= order.assignment.pass_m


def test_sixteen_robots_crossing_a_roundabout_go_in_two_waves_and_all_park() -> None:
    """Sixteen robots on a ring round one post, each to the antipodal point: all at once
    they fill the circle round the post's zone and crawl (offline, none parked within
    150 s); every other one in a second wave (the planner's order "these go, those
    follow") they all park -- and none of the second wave stands on a goal of the first.
    The second wave is every other robot but those the rollouts let go at once (one of
    the eight since the filter's side on a via leg, 3c54f82): never two neighbours."""
    post = ObstacleSpec(x=0.0, y=0.0, radius=1.6, body=0.8)
    scenario = ring_round_posts(16, 8.0, [post], "ring-16", seed=0)
    fleet = OfflineFleet(scenario)
    fleet.submit_arrived()
    work = fleet.snapshot()
    first = plan(work.snapshot)
    waits = {d.robot_id for d in first.decisions if d.start_delay_s > 0.0}
    assert len(waits) >= 6
    ring = scenario.robot_ids  # in order round the circle
    assert not any(ring[k] in waits and ring[(k + 1) % 16] in waits for k in range(16))
    run = run_closed_loop(scenario, "auto", plan, time_limit_s=60.0)
    assert run.success_rate == 1.0 and run.collisions == 0


def test_the_offline_fleet_holds_the_corridor_one_robot_at_a_time_as_the_service_does() -> None:
    """The corridor between two rooms is too narrow for two robots to pass: the service
    holds it as a single-robot zone (a narrow passage found in the walls), and so does the
    offline fleet now -- without it, robots from both rooms met nose to nose inside and two
    of six parked in 300 s."""
    scenario = corridor()
    fleet = OfflineFleet(scenario)
    assert [z.name for z in fleet.ledger.zones.shapes] == ["passage-1"]
    run = run_closed_loop(scenario, "auto", plan, time_limit_s=120.0)
    assert run.success_rate == 1.0 and run.collisions == 0
