"""The planner's contract on scenes worth naming: swaps, a robot that must wait, holds,
robots under way (keep, revise), lost robots, corridors."""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import replace

import pytest
from planning import TOL, idle, moved_on, queued, replay, scene, swap2

from fleet.core.geometry import segment_distance, segments_cross
from fleet.core.params import Avoidance, RobotProfile, SafetyConfig
from fleet.core.planner import (
    Plan,
    PlannerConfig,
    PlanningSnapshot,
    RobotSnapshot,
    TaskDecision,
    TaskSnapshot,
    left_corridor,
    plan,
)
from fleet.core.tasks import DEFAULT_GAINS, RobotStatus, TaskStatus
from fleet.core.types import Law, Posture
from fleet.core.wire import Obstacle


def by_task(result: Plan) -> dict[str, TaskDecision]:
    return {d.task_id: d for d in result.decisions}


@pytest.mark.parametrize("mirror", [False, True], ids=["chirality-a", "chirality-b"])
def test_a_swap_of_two_gets_a_safe_plan_in_both_chiralities(mirror: bool) -> None:
    snapshot = swap2(mirror)
    result = plan(snapshot)
    assert result.safe and result.waiting == 0 and result.snapshot_version == 1
    assert {(d.task_id, d.robot_id, d.action, d.hold) for d in result.decisions} == {
        ("t0", "r0", "assign", False),
        ("t1", "r1", "assign", False),
    }
    assert result.min_separation_m >= snapshot.separation_m
    run = replay(snapshot, result)  # the plan, run by the simulator on its own
    assert run.worst_shortfall(snapshot.separation_m) <= 0
    assert run.result.done.all()
    for i, d in enumerate(result.decisions):
        assert d.predicted_arrival_s == pytest.approx(float(run.result.time[i]), abs=0.05)


CROSSING = dict(
    starts=[(-4.0, 0.0, 0.0), (0.0, -4.0, math.pi / 2)],
    goals=[(4.0, 0.0, 0.0), (0.0, 4.0, math.pi / 2)],
)
#: [m] what the crossing keeps: more than the default gains' cw laws keep there (0.97 m)
CROSSING_SEPARATION = 1.2


def test_a_robot_waits_for_a_peer_to_pass_when_it_must() -> None:
    """Two robots crossing at right angles reach the middle together; with fixed laws and
    1.2 m to keep, the repulsion alone cannot keep them apart: one must wait."""
    sep = CROSSING_SEPARATION
    snapshot = scene(**CROSSING, separation=sep, direction="cw")  # type: ignore[arg-type]
    both_go = Plan(
        1,
        tuple(TaskDecision(f"t{i}", f"r{i}", "assign", "cw") for i in range(2)),  # no waiting
        True,
        0.0,
    )
    assert replay(snapshot, both_go).worst_shortfall(sep) > 0  # so waiting is needed
    result = plan(snapshot)
    assert result.safe and result.waiting == 0
    waits = [d for d in result.decisions if d.start_delay_s > 0]
    assert len(waits) == 1 and not waits[0].hold
    run = replay(snapshot, result)
    assert run.worst_shortfall(sep) <= 0 and run.result.done.all()


def test_when_no_option_is_safe_the_new_robots_hold_with_the_reason() -> None:
    no_relaxing = PlannerConfig(standstill_margin_m=10.0)  # the standstill rule stays out
    result = plan(swap2(separation=5.0), no_relaxing)  # no way round keeps 5 m on a 6 m swap
    assert result.safe and result.waiting == 2  # safe: it moves nobody
    for d in result.decisions:
        assert d.action == "assign" and d.hold
        assert d.reason is not None and "waiting" in d.reason
        assert d.predicted_arrival_s is None
    assert result.replan_in_s is not None  # held robots are planned again


def test_a_standstill_of_new_robots_is_planned_at_contact_distance_plus_a_margin() -> None:
    strict = swap2(separation=5.0)  # no way round keeps 5 m on a 6 m swap
    result = plan(strict)
    floor = 2 * strict.profile.radius + 0.02
    assert result.waiting == 0 and result.safe and result.min_separation_m >= floor
    assert any(n.startswith("standstill") for n in result.notes)
    assert replay(strict, result).worst_shortfall(floor) <= 1e-9


def test_robots_under_way_that_no_option_keeps_apart_part_at_the_contact_guards_reach() -> None:
    first = swap2()
    under_way = moved_on(first, plan(first), 0.5)  # both driving, 6 m apart
    strict = dataclasses.replace(under_way, separation_m=5.0)  # no way round keeps 5 m
    result = plan(strict)
    floor = 2 * strict.profile.radius + 0.02
    assert any(not d.hold for d in result.decisions)  # a standstill would last for ever
    assert result.safe and result.min_separation_m >= floor
    assert any(n.startswith("standstill") for n in result.notes)
    run = replay(under_way, result)
    assert run.worst_shortfall(floor) <= 1e-9


def test_nothing_to_plan_without_an_available_robot() -> None:
    snapshot = swap2()
    busy = tuple(
        RobotSnapshot(r.robot_id, r.pose, RobotStatus.DRIVING, available=False)
        for r in snapshot.robots
    )
    result = plan(dataclasses.replace(snapshot, robots=busy))
    assert result.decisions == () and result.safe


def test_unnamed_tasks_go_to_the_nearest_robots() -> None:
    robots = (idle("near", (0.0, 0.0, 0.0)), idle("far", (9.0, 9.0, 0.0)))
    tasks = (queued("t", (2.0, 0.0, 0.0), None),)
    result = plan(PlanningSnapshot(1, robots, tasks, control_dt=0.05))
    assert [(d.task_id, d.robot_id, d.action) for d in result.decisions] == [
        ("t", "near", "assign")
    ]


def test_robots_under_way_that_are_safe_are_kept_with_a_fresh_corridor() -> None:
    snapshot = swap2()
    first = plan(snapshot)
    again = plan(moved_on(snapshot, first, 0.0))
    assert [d.action for d in again.decisions] == ["keep", "keep"]
    for old, new in zip(first.decisions, again.decisions, strict=True):
        assert new.law == old.law and new.corridor and not new.hold
        assert new.predicted_arrival_s == pytest.approx(old.predicted_arrival_s, abs=0.05)


def test_a_robot_under_way_on_a_collision_course_is_revised() -> None:
    """Both robots already drive at each other with laws that do not keep 1.2 m: the plan
    changes at least one (flip, wait or hold) as a new revision, and is safe."""
    snapshot = scene(**CROSSING, separation=CROSSING_SEPARATION)  # type: ignore[arg-type]
    driving = tuple(
        dataclasses.replace(t, status=TaskStatus.DRIVING, robot_id=f"r{i}", law="cw", revision=3)
        for i, t in enumerate(snapshot.tasks)
    )
    robots = tuple(
        RobotSnapshot(r.robot_id, r.pose, RobotStatus.DRIVING, False, f"t{i}", "cw", 3)
        for i, r in enumerate(snapshot.robots)
    )
    moving = dataclasses.replace(snapshot, robots=robots, tasks=driving)
    result = plan(moving)
    revised = [d for d in result.decisions if d.action == "revise"]
    assert revised and all(d.revision == 3 for d in revised)
    assert replay(moving, result).worst_shortfall(CROSSING_SEPARATION) <= 0


def _driving_alone(law: Law, pose: Posture, goal: Posture) -> PlanningSnapshot:
    """One robot under way (revision 2) with ``law`` from ``pose`` to ``goal``."""
    snapshot = scene([pose], [goal])
    task = dataclasses.replace(
        snapshot.tasks[0], status=TaskStatus.DRIVING, robot_id="r0", law=law, revision=2
    )
    robot = RobotSnapshot("r0", pose, RobotStatus.DRIVING, False, "t0", law, 2)
    return dataclasses.replace(snapshot, robots=(robot,), tasks=(task,))


#: A robot 1.3 m short of its goal (2.5, -1.2, 0) heading 63 degrees: law (17) turns it
#: counter-clockwise the long way round (297 degrees), law (20) turns it back 63 degrees.
PAST_ITS_HEADING = (1.30, -1.75, math.radians(63.0))


def test_a_robot_under_way_turned_past_its_goal_takes_the_law_that_turns_back() -> None:
    """Disturbed, a robot under way may be turned past its goal's heading in its law's
    rotation sense: that law goes the long way round. Within ``flip_within_m`` of its goal
    the plan flips it, as a revision, when the other law alone arrives more than
    ``flip_gain_s`` sooner -- and the robot (the replay) arrives as predicted, sooner than
    it would have kept on."""
    snapshot = _driving_alone("ccw", PAST_ITS_HEADING, (2.5, -1.2, 0.0))
    kept = plan(snapshot, PlannerConfig(flip_gain_s=math.inf))
    result = plan(snapshot)
    (before,), (d,) = kept.decisions, result.decisions
    assert (before.action, before.law) == ("keep", "ccw")
    farther = plan(snapshot, PlannerConfig(flip_within_m=1.0))  # 1.3 m from its goal
    assert [(f.action, f.law) for f in farther.decisions] == [("keep", "ccw")]
    assert (d.action, d.law, d.revision) == ("revise", "cw", 2) and not d.hold
    assert d.predicted_arrival_s is not None and before.predicted_arrival_s is not None
    assert d.predicted_arrival_s < before.predicted_arrival_s - PlannerConfig().flip_gain_s
    run = replay(snapshot, result)
    assert float(run.result.time[0]) == pytest.approx(d.predicted_arrival_s, abs=0.05)


@pytest.mark.parametrize("law", ["ccw", "cw"])
def test_a_robot_under_way_whose_other_law_is_not_much_faster_keeps_its_law(law: Law) -> None:
    """Near its goal's heading both laws arrive within a fraction of a second of each
    other: no flip (a stable plan stays stable)."""
    snapshot = _driving_alone(law, (2.25, -1.38, math.radians(347.0)), (2.5, -1.2, 0.0))
    (d,) = plan(snapshot).decisions
    assert (d.action, d.law) == ("keep", law)


@pytest.mark.parametrize("field", ["flip_gain_s", "flip_within_m"])
@pytest.mark.parametrize("value", [-1.0, math.nan])
def test_a_negative_or_nan_flip_bound_is_refused_with_its_name(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        PlannerConfig(**{field: value})  # type: ignore[arg-type]


def test_a_lost_robot_far_away_is_not_part_of_the_plan() -> None:
    snapshot = swap2()
    lost = RobotSnapshot("gone", (80.0, 80.0, 0.0), RobotStatus.LOST, available=False)
    with_lost = dataclasses.replace(snapshot, robots=(*snapshot.robots, lost))
    assert by_task(plan(with_lost)) == by_task(plan(snapshot))


def with_lost(y: float) -> PlanningSnapshot:
    """One robot driving along the x axis past a lost robot at (0, ``y``)."""
    free = scene([(-4.0, 0.0, 0.0)], [(4.0, 0.0, 0.0)])
    lost = RobotSnapshot("gone", (0.0, y, 0.0), RobotStatus.LOST, available=False)
    return dataclasses.replace(free, robots=(*free.robots, lost))


def test_a_lost_robot_beside_the_way_is_an_obstacle() -> None:
    snapshot = with_lost(0.8)
    result = plan(snapshot)
    (d,) = result.decisions
    assert not d.hold
    assert d.predicted_min_separation_m < 1.0  # it passes the lost robot, knowing it is there
    assert replay(snapshot, result).worst_shortfall(0.5) <= 0


def test_a_robot_with_a_lost_robot_straight_ahead_is_steered_around_it_by_the_filter() -> None:
    """Neither law bends a straight run, but the safety filter (which the rollouts run, as
    the robots do) turns the robot past the lost one: no hold, no standstill relaxation,
    and the independent replay keeps the separation."""
    snapshot = with_lost(0.0)
    result = plan(snapshot, PlannerConfig(standstill_margin_m=10.0))
    (d,) = result.decisions
    assert not d.hold and d.predicted_min_separation_m >= 0.5
    assert not any(n.startswith("standstill") for n in result.notes)
    assert replay(snapshot, result).worst_shortfall(0.5) <= 0


def test_the_corridor_follows_the_predicted_path_and_is_left_elsewhere() -> None:
    result = plan(swap2())
    for d in result.decisions:
        t0, x0, y0 = d.corridor[0]
        assert t0 == 0.0
        for t, x, y in d.corridor[:: max(1, len(d.corridor) // 10)]:
            assert not left_corridor(d.corridor, t, x, y, 0.05, 0.0)
        assert left_corridor(d.corridor, 0.0, x0 + 3.0, y0, 0.5, 1.0)


def test_a_task_under_way_with_a_lost_robot_gets_no_decision() -> None:
    snapshot = swap2()
    t0 = dataclasses.replace(snapshot.tasks[0], status=TaskStatus.DRIVING, robot_id="r0", law="cw")
    r0 = RobotSnapshot("r0", snapshot.robots[0].pose, RobotStatus.LOST, False, "t0", "cw")
    result = plan(
        dataclasses.replace(
            snapshot, robots=(r0, snapshot.robots[1]), tasks=(t0, snapshot.tasks[1])
        )
    )
    assert [d.task_id for d in result.decisions] == ["t1"]


def test_fixed_directions_are_respected() -> None:
    result = plan(scene(**CROSSING, direction="ccw"))  # type: ignore[arg-type]
    assert {d.law for d in result.decisions} == {"ccw"}


def test_held_tasks_are_released_once_it_is_safe() -> None:
    snapshot = swap2()
    held = tuple(
        TaskSnapshot(
            task_id=t.task_id,
            goal=t.goal,
            direction="auto",
            gains=dict(DEFAULT_GAINS),
            tolerance=TOL,
            status=TaskStatus.WAITING,
            created_at=t.created_at,
            named_robot=t.named_robot,
            robot_id=t.named_robot,
            law="ccw",
            revision=1,
            hold=True,
        )
        for t in snapshot.tasks
    )
    robots = tuple(
        RobotSnapshot(r.robot_id, r.pose, RobotStatus.WAITING, False, f"t{i}", "ccw", 1)
        for i, r in enumerate(snapshot.robots)
    )
    result = plan(dataclasses.replace(snapshot, robots=robots, tasks=held))
    assert result.waiting == 0
    assert all(d.action == "revise" and not d.hold and d.revision == 1 for d in result.decisions)


def test_robots_under_way_are_rolled_on_until_the_plan_reaches_them() -> None:
    snapshot = swap2()
    first = plan(snapshot)
    under_way = max(d.start_delay_s for d in first.decisions)  # every start delay over
    moving = dataclasses.replace(moved_on(snapshot, first, under_way), lead_time_s=1.0)
    result = plan(moving)
    for r, d in zip(moving.robots, result.decisions, strict=True):
        t0, x0, y0 = d.corridor[0]
        assert t0 == 0.0 and d.action == "keep"
        assert 0.1 < math.dist((x0, y0), r.pose[:2]) < 1.5  # where it will be in 1 s


def test_static_obstacles_are_avoided_and_known_to_the_prediction() -> None:
    """The paper's comparative case III: (0, 2, 0) to (0, -2, 0) between two obstacles."""
    from fleet.core.wire import Obstacle
    from fleet.paper.scenarios import SCENARIOS

    case = SCENARIOS["III"]
    snapshot = dataclasses.replace(
        scene([case.start], [case.goal]),
        obstacles=(Obstacle(x=0.8, y=0.0, radius=1.0), Obstacle(x=-0.8, y=0.0, radius=1.0)),
    )
    result = plan(snapshot)
    (d,) = result.decisions
    assert result.safe and not d.hold and d.predicted_arrival_s is not None
    run = replay(snapshot, result)
    assert run.result.done.all()
    assert float(run.result.time[0]) == pytest.approx(d.predicted_arrival_s, abs=1e-6)


def test_a_route_the_robot_cannot_drive_is_dropped_for_the_straight_way_it_can() -> None:
    """Case III's posts with a robot crossing them on the diagonal: the route graph threads
    it through the gap, where both posts' Eq. (27) zones stall the law short of the
    via-points; straight, the law takes it round a post."""
    posts = (
        Obstacle(x=0.8, y=0.0, radius=1.0, body=0.2),
        Obstacle(x=-0.8, y=0.0, radius=1.0, body=0.2),
    )
    snapshot = replace(scene([(-2.5, 1.2, 0.0)], [(2.5, -1.2, 0.0)]), obstacles=posts)
    result = plan(snapshot)
    (d,) = result.decisions
    assert result.safe and d.action == "assign" and not d.hold
    assert d.route == () and d.predicted_arrival_s is not None
    run = replay(snapshot, result)
    assert run.result.done.all()
    assert float(run.result.time[0]) == pytest.approx(d.predicted_arrival_s, abs=1e-6)


def test_a_robot_routed_round_the_posts_zones_goes_round_a_standing_robot_outside_them() -> None:
    """A robot a stuck recovery sent round case III's posts' Eq. (27) zones (``wide_way``),
    with a robot parked on that way round: the way round the parked robot stays outside
    the zones too (through the gap, the posts' terms stalled it in the mouth again)."""
    posts = (
        Obstacle(x=0.8, y=0.0, radius=1.0, body=0.2),
        Obstacle(x=-0.8, y=0.0, radius=1.0, body=0.2),
    )
    start = (-0.6, -1.5, math.pi / 2)
    task = replace(
        queued("t0", (0.0, 3.2, math.pi / 2), "r0", direction="ccw"),
        status=TaskStatus.DRIVING,
        robot_id="r0",
        law="ccw",
        wide_way=True,
    )
    driving = RobotSnapshot("r0", start, RobotStatus.DRIVING, False, "t0", "ccw")

    def route(*standing: tuple[float, float]) -> tuple[tuple[float, float], ...]:
        robots = (driving, *(idle(f"s{k}", (*xy, 0.0)) for k, xy in enumerate(standing)))
        snapshot = PlanningSnapshot(
            version=1, robots=robots, tasks=(task,), obstacles=posts, control_dt=0.05
        )
        (d,) = plan(snapshot).decisions
        assert d.predicted_arrival_s is not None
        return d.route

    right = posts[0]
    parked = max(route(), key=lambda p: p[0])  # its way's east end, where a robot now stands
    assert parked[0] > right.x + right.radius  # round the right post's zone: counter-clockwise
    way = route(parked)
    assert way and all(math.dist(p, parked) > Avoidance().peer_radius for p in way)
    assert all(math.dist(p, (o.x, o.y)) >= o.radius for p in way for o in posts)
    legs = itertools.pairwise([start[:2], *way])
    assert not any(segments_cross(a, b, (-0.8, 0.0), (0.8, 0.0)) for a, b in legs)


def test_robots_sent_round_the_posts_zones_from_either_side_go_round_them_one_way() -> None:
    """Two robots a stuck recovery sent round case III's posts' zones (``wide_way``), one
    above the pair bound south, one at its north-west corner bound south-east: both go
    round the pair counter-clockwise (the second's way clockwise along the top is much
    shorter, and took it head-on into the first for 80 s of a disturbed benchmark run)."""
    posts = (
        Obstacle(x=0.8, y=0.0, radius=1.0, body=0.2),
        Obstacle(x=-0.8, y=0.0, radius=1.0, body=0.2),
    )
    starts = {"r0": (0.1, 1.1, -math.pi / 2), "r1": (-0.8, 0.9, 0.0)}
    goals = {"r0": (0.0, -2.0, 0.0), "r1": (2.5, -1.2, 0.0)}
    driving = {"status": TaskStatus.DRIVING, "law": "ccw", "wide_way": True}
    tasks = tuple(
        replace(queued(f"t{r}", goals[r], r, direction="ccw"), robot_id=r, **driving)
        for r in starts
    )
    robots = tuple(
        RobotSnapshot(r, starts[r], RobotStatus.DRIVING, False, f"t{r}", "ccw") for r in starts
    )
    snapshot = PlanningSnapshot(
        version=1, robots=robots, tasks=tasks, obstacles=posts, control_dt=0.05
    )
    for d in plan(snapshot).decisions:
        start = starts[d.robot_id][:2]
        angles = [math.atan2(y, x) for x, y in (start, *d.route)]
        turned = sum(math.remainder(b - a, math.tau) for a, b in itertools.pairwise(angles))
        assert d.route and turned > math.pi / 2, (d.robot_id, d.route)


@pytest.mark.parametrize(
    ("other_is", "at"),
    [("gave way", (0.7, 0.0)), ("standing", (0.7, 0.0)), ("holding off", (0.8, 0.5))],
)
def test_a_robot_is_routed_round_one_that_gave_way_stands_ahead_or_held_it_off(
    other_is: str, at: tuple[float, float]
) -> None:
    """The mover's goal lies behind the other robot (the laws drive straight at a robot
    dead ahead, Eq. (27) only slows them): the other gave way in a standoff and stands;
    or stands with no task on the mover's straight way (no flag needed); or stands beside
    that way, within its influence radius, and held the mover off in a standoff
    (``round_robots``). The mover's way -- its last leg, with no post to route round --
    goes round it, backing out of its zone first when the mover is in it, its legs beyond
    two bodies and the contact margin; the plan's prediction is what the robots do and the
    mover parks -- held off beside its way, sooner than the law's own way past it."""

    def snapshot(flagged: bool) -> PlanningSnapshot:
        driving = replace(
            queued("t0", (4.0, 0.0, 0.0), "r0"),
            status=TaskStatus.DRIVING, robot_id="r0", law="cw",
            round_robots=("r1",) if flagged and other_is == "holding off" else (),
        )  # fmt: skip
        mover = RobotSnapshot("r0", (0.0, 0.0, 0.0), RobotStatus.AVOIDING, False, "t0", "cw")
        if other_is != "gave way":
            other = idle("r1", (*at, math.pi))
            return PlanningSnapshot(
                version=1, robots=(mover, other), tasks=(driving,), control_dt=0.05
            )
        held = replace(
            queued("t1", (-3.0, 0.0, math.pi), "r1", 1.0, direction="ccw"),
            status=TaskStatus.WAITING, robot_id="r1", law="ccw", hold=True, gave_way=flagged,
        )  # fmt: skip
        other = RobotSnapshot("r1", (*at, math.pi), RobotStatus.WAITING, False, "t1", "ccw")
        return PlanningSnapshot(
            version=1, robots=(mover, other), tasks=(driving, held), control_dt=0.05
        )

    unflagged = {d.robot_id: d for d in plan(snapshot(False)).decisions}["r0"]
    assert (unflagged.route == ()) == (other_is != "standing")
    snap = snapshot(True)
    result = plan(snap)
    decided = {d.robot_id: d for d in result.decisions}
    way = decided["r0"].route
    assert way and result.safe
    assert math.dist(way[0], at) >= Avoidance().peer_radius  # backed out first
    reach = 2 * RobotProfile().radius + SafetyConfig().contact_margin_m
    legs = itertools.pairwise([(0.0, 0.0), *way, (4.0, 0.0)])
    assert all(segment_distance(*at, a, b) >= reach for a, b in legs)
    run = replay(snap, result)
    assert run.result.done[: len(snap.tasks)].all()
    arrival = decided["r0"].predicted_arrival_s
    assert arrival is not None and float(run.result.time[0]) == pytest.approx(arrival, abs=1e-6)
    if other_is == "holding off":
        assert unflagged.predicted_arrival_s is not None
        assert arrival < unflagged.predicted_arrival_s


def test_a_robot_in_a_gate_beside_a_standing_robot_is_not_sent_round_the_whole_wall(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A mover in a wall's 2 m gate, 0.9 m from a robot standing just past it (within its
    zone): backing out of the zone first, the standing robot's whole grown body closes the
    gate, and the way round it runs round the wall's far end (seen in the garage: a route
    round the whole garage, 38 s lost). The way round the body shrunk to where the mover is
    stays in the gate -- taken, as the back-out way is that much longer
    (``ROUND_DETOUR_M``) -- and the plan predicts the mover parks."""
    from fleet.core.planner import scene as scene_module

    walls = (
        Obstacle(x=0.0, y=-10.0, end=(0.0, -1.0), radius=0.3, body=0.05),
        Obstacle(x=0.0, y=1.0, end=(0.0, 10.0), radius=0.3, body=0.05),
    )
    driving = replace(
        queued("t0", (4.0, 0.0, 0.0), "r0"), status=TaskStatus.DRIVING, robot_id="r0", law="cw"
    )
    mover = RobotSnapshot("r0", (0.1, 0.0, 0.0), RobotStatus.DRIVING, False, "t0", "cw")
    snap = PlanningSnapshot(
        version=1, robots=(mover, idle("r1", (1.0, 0.0, 0.0))), tasks=(driving,),
        obstacles=walls, control_dt=0.05,
    )  # fmt: skip

    def far_side(result: Plan) -> float:
        (decided,) = result.decisions
        assert decided.route and result.safe and decided.predicted_arrival_s is not None
        return max(abs(y) for _, y in decided.route)

    assert far_side(plan(snap)) < 2.0  # through the gate
    monkeypatch.setattr(scene_module, "ROUND_DETOUR_M", math.inf)
    assert far_side(plan(snap)) > 9.0  # backed out: round the wall's end


@pytest.mark.parametrize("heading", [0.0, math.pi / 2, -math.pi / 2])
@pytest.mark.parametrize("radius", [None, 0.35])
def test_the_plan_sees_a_standing_robot_as_it_is_its_heading_and_its_own_body(
    heading: float, radius: float | None
) -> None:
    """A robot standing beside a mover's way, facing ``heading``, with its own body
    (described) or the fleet's: the safety filter's constraint lies ahead of a peer's axle
    and round its body, so the plan's predicted arrival is the replay's to the step only
    when the rollouts give a standing robot its heading and its profile."""
    driving = replace(
        queued("t0", (4.0, 0.0, 0.0), "r0"), status=TaskStatus.DRIVING, robot_id="r0", law="cw"
    )
    mover = RobotSnapshot("r0", (0.0, 0.0, 0.0), RobotStatus.DRIVING, False, "t0", "cw")
    profile = None if radius is None else RobotProfile(radius=radius)
    beside = replace(idle("r1", (2.0, 0.7, heading)), profile=profile)
    snap = PlanningSnapshot(version=1, robots=(mover, beside), tasks=(driving,), control_dt=0.05)
    result = plan(snap)
    (decided,) = result.decisions
    run = replay(snap, result)
    assert decided.predicted_arrival_s is not None and result.safe
    assert float(run.result.time[0]) == pytest.approx(decided.predicted_arrival_s, abs=1e-6)


def test_a_task_taken_from_a_stuck_robot_goes_to_another_one_and_keeps_its_revision() -> None:
    near, far = idle("near", (2.0, 0.0, 0.0)), idle("far", (-4.0, 4.0, 0.0))
    requeued = replace(queued("t", (4.0, 0.0, 0.0), None, 1.0), revision=3)
    snapshot = PlanningSnapshot(version=1, robots=(near, far), tasks=(requeued,), control_dt=0.05)
    (first,) = plan(snapshot).decisions
    assert (first.robot_id, first.revision) == ("near", 3)  # the nearer robot is cheaper
    avoiding = replace(requeued, avoid_robot="near")
    (moved,) = plan(replace(snapshot, tasks=(avoiding,))).decisions
    assert (moved.robot_id, moved.action, moved.revision) == ("far", "assign", 3)
    alone = replace(snapshot, robots=(near,), tasks=(avoiding,))
    (back,) = plan(alone).decisions  # no other robot: it goes back rather than wait for ever
    assert back.robot_id == "near"


#: A wall across the way of a robot from (-3, 0) to (3, 0).
WALL = Obstacle(x=0.0, y=-1.5, end=(0.0, 1.5), radius=0.3, body=0.05)


def test_a_robot_behind_a_wall_is_routed_round_it_and_the_plan_predicts_its_run() -> None:
    snapshot = replace(scene([(-3.0, 0.0, 0.0)], [(3.0, 0.0, 0.0)]), obstacles=(WALL,))
    result = plan(snapshot)
    (d,) = result.decisions
    assert d.action == "assign" and d.route and max(abs(y) for _, y in d.route) > 1.5
    assert d.route[-1] == pytest.approx((2.0, 0.0))  # the pre-bay point, 1 m before the goal
    run = replay(snapshot, result)  # the robot following the route on its own
    assert run.result.done.all()
    assert d.predicted_arrival_s == pytest.approx(float(run.result.time[0]), abs=0.05)
    # the wall gone, the same task goes straight
    assert plan(replace(snapshot, obstacles=())).decisions[0].route == ()


def test_a_robot_past_its_last_via_point_is_predicted_straight_to_its_goal() -> None:
    """Past the pre-bay point nothing of the route is left: the plan predicts the law's
    last leg (not a turn back to the point) and says so, so no revision is sent."""
    snapshot = replace(scene([(-3.0, 0.0, 0.0)], [(3.0, 0.0, 0.0)]), obstacles=(WALL,))
    first = plan(snapshot)
    (d0,) = first.decisions
    run = replay(snapshot, first)
    later = moved_on(snapshot, first, 0.9 * float(run.result.time[0]))
    x, y, _ = later.robots[0].pose
    assert x > d0.route[-1][0] and math.dist((x, y), (3.0, 0.0)) < 1.0  # past the pre-bay point
    (d,) = plan(later).decisions
    assert d.route == () and d.last_leg and d.action == "keep"
    assert d.predicted_arrival_s is not None
    assert 0.9 * float(run.result.time[0]) + d.predicted_arrival_s == pytest.approx(
        float(run.result.time[0]), abs=0.1
    )


def test_a_robot_under_way_keeps_the_rest_of_the_route_it_was_sent() -> None:
    snapshot = replace(scene([(-3.0, 0.0, 0.0)], [(3.0, 0.0, 0.0)]), obstacles=(WALL,))
    first = plan(snapshot)
    shortest = first.decisions[0].route
    other_way = tuple((x, -y) for x, y in shortest)  # round the wall's other end
    later = moved_on(snapshot, first, 1.0)
    task = replace(later.tasks[0], route=other_way)
    (d,) = plan(replace(later, tasks=(task,))).decisions
    assert d.route == other_way  # not re-routed from scratch


def test_a_robot_pushed_off_its_route_is_routed_again_from_where_it_is() -> None:
    snapshot = replace(scene([(-3.0, 0.0, 0.0)], [(3.0, 0.0, 0.0)]), obstacles=(WALL,))
    first = plan(snapshot)
    later = moved_on(snapshot, first, 1.0)
    side = 1.0 if max(y for _, y in first.decisions[0].route) > 1.5 else -1.0  # its way round
    # pushed along the wall towards its other end: that end is the way round now
    robot = replace(later.robots[0], pose=(-0.6, -1.2 * side, 0.0))
    (d,) = plan(replace(later, robots=(robot,))).decisions
    assert d.route and min(side * y for _, y in d.route) < -1.5  # round the other end
    # still beside its route, it keeps the rest of it
    beside = replace(later.robots[0], pose=(0.6, 0.3 * side, 0.0))
    (kept,) = plan(replace(later, robots=(beside,))).decisions
    assert kept.route == first.decisions[0].route[-len(kept.route) :]
