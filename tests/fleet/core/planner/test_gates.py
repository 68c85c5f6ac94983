"""Single-robot zones in a plan: one robot at a time through a zone, the others wait for
it with the zone named; the order (driving first, nearest next, blockers before the
blocked); a plan's decisions carry the zones they hold."""

from __future__ import annotations

import math

import numpy as np
from planning import idle, queued, replay

from fleet.core.planner import PlanningSnapshot, plan
from fleet.core.planner.gates import gate
from fleet.core.zones import ZonePass, ZoneShape

GATE = ZoneShape("gate", ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)))
NO_ROUTE = np.zeros((0, 2))


def poses(*xy: tuple[float, float]) -> np.ndarray:
    return np.array([(x, y, 0.0) for x, y in xy], dtype=np.float64)


def test_the_robot_nearer_the_zone_goes_first_and_the_other_waits_naming_it() -> None:
    g = gate(
        [GATE],
        {},
        ["far", "near"],
        np.array([False, False]),
        poses((-6.0, 0.0), (3.0, 0.0)),
        [NO_ROUTE, NO_ROUTE],
        poses((6.0, 0.0), (-6.0, 0.0)),
        [0.0, 1.0],
    )
    assert g.granted == ((), (ZonePass("gate", (1.0, 0.0), (-1.0, 0.0)),))
    assert g.must_hold.tolist() == [True, False]
    assert g.waits_for == ("gate", None)
    assert g.reasons[0] == "waiting for single-robot zone gate (held by near)"


def test_a_robot_driving_goes_first_and_a_robot_standing_in_the_zone_holds_it() -> None:
    starts = poses((-6.0, 0.0), (3.0, 0.0))
    goals = poses((6.0, 0.0), (-6.0, 0.0))
    driving = gate([GATE], {}, ["far", "near"], np.array([True, False]), starts,
                   [NO_ROUTE, NO_ROUTE], goals, [0.0, 1.0])  # fmt: skip
    assert driving.must_hold.tolist() == [False, True]
    lost = gate([GATE], {"gate": {"lost-one": None}}, ["far", "near"], np.array([True, False]),
                starts, [NO_ROUTE, NO_ROUTE], goals, [0.0, 1.0])  # fmt: skip
    assert lost.must_hold.tolist() == [True, True]
    assert lost.reasons[1] == "waiting for single-robot zone gate (held by lost-one)"


def test_a_robot_standing_in_a_zone_another_holds_goes_on_and_the_holder_waits() -> None:
    """A robot got into a convoy zone another robot holds going the other way (swung in by
    a stuck recovery: case III with four robots, one held in the gap for 100 s while the
    gap's holder stood at its mouth): it holds the zone too (the zone book records it
    standing in it, pass None), so it goes on, out of it, and the holder waits."""
    convoy = ZoneShape("gate", GATE.outline, convoys=True)
    west = ZonePass("gate", (1.0, 0.0), (-1.0, 0.0))
    holders = {"gate": {"holder": west, "inside": None}}
    g = gate([convoy], holders, ["holder", "inside"], np.array([True, False]),
             poses((2.0, 0.5), (0.2, 0.3)), [NO_ROUTE, NO_ROUTE],
             poses((-6.0, 0.0), (6.0, 0.0)), [0.0, 1.0])  # fmt: skip
    assert g.must_hold.tolist() == [True, False]
    assert g.reasons[0] == "waiting for single-robot zone gate (held by inside)"
    assert [p.zone for p in g.granted[1]] == ["gate"]


def test_a_robot_whose_way_passes_the_others_goal_goes_before_it() -> None:
    starts = poses((-6.0, 0.0), (3.0, 0.0))
    goals = poses((6.0, 0.0), (-6.0, 0.0))
    blocks = np.array([[False, True], [False, False]])  # "far" must pass before "near" parks
    g = gate([GATE], {}, ["far", "near"], np.array([False, False]), starts,
             [NO_ROUTE, NO_ROUTE], goals, [0.0, 1.0], blocks)  # fmt: skip
    assert g.must_hold.tolist() == [False, True]


def test_a_way_that_misses_the_zone_needs_nothing() -> None:
    g = gate([GATE], {"gate": {"other": None}}, ["r"], np.array([False]), poses((-6.0, 5.0)),
             [np.array([[0.0, 5.0]])], poses((6.0, 5.0)), [0.0])  # fmt: skip
    assert g.granted == ((),) and not g.must_hold.any()


def corridor_swap(
    holders: tuple[tuple[str, str, ZonePass | None], ...] = (), zone: ZoneShape = GATE
) -> PlanningSnapshot:
    """Two robots 5 m either side of a 2 m gate zone, each bound for the other's side."""
    robots = (idle("r0", (-5.0, 0.0, 0.0)), idle("r1", (5.0, 0.2, math.pi)))
    tasks = (
        queued("t0", (5.0, -2.0, 0.0), "r0", 0.0),
        queued("t1", (-5.0, 2.0, math.pi), "r1", 1.0),
    )
    return PlanningSnapshot(
        version=1, robots=robots, tasks=tasks, control_dt=0.05, zones=(zone,),
        zone_holders=holders,
    )  # fmt: skip


def test_a_plan_sends_one_robot_through_the_zone_and_holds_the_other_for_it() -> None:
    snapshot = corridor_swap()
    result = plan(snapshot)
    d = {x.task_id: x for x in result.decisions}
    going = [x for x in d.values() if not x.hold]
    waiting = [x for x in d.values() if x.hold]
    assert len(going) == 1 and len(waiting) == 1
    assert [p.zone for p in going[0].zones] == ["gate"] and going[0].waits_for is None
    assert waiting[0].zones == () and waiting[0].waits_for == "gate"
    assert waiting[0].reason == f"waiting for single-robot zone gate (held by {going[0].robot_id})"
    assert result.replan_in_s is not None  # the waiting robot is tried again
    run = replay(snapshot, result)
    moving = int(going[0].robot_id[1:])
    assert run.result.done[moving]


def test_no_robot_moves_through_a_zone_a_third_robot_holds_and_no_margin_is_relaxed() -> None:
    result = plan(corridor_swap(holders=(("gate", "r9", None),)))
    assert all(x.hold and x.waits_for == "gate" for x in result.decisions)
    assert not any("standstill" in n for n in result.notes)


CONVOY = ZoneShape("aisle", GATE.outline, convoys=True)


def test_in_a_convoy_zone_robots_going_the_same_way_follow_and_the_other_way_waits() -> None:
    starts = poses((-6.0, 0.0), (-8.0, 0.5), (6.0, 0.0))
    goals = poses((6.0, 2.0), (6.0, -2.0), (-6.0, 2.0))
    g = gate([CONVOY], {}, ["lead", "next", "back"], np.array([False, False, False]), starts,
             [NO_ROUTE] * 3, goals, [0.0, 1.0, 2.0])  # fmt: skip
    assert g.must_hold.tolist() == [False, False, True]
    assert [p.zone for p in g.granted[1]] == ["aisle"]
    assert g.reasons[2] == "waiting for single-robot zone aisle (held by lead going the other way)"
    single = gate([GATE], {}, ["lead", "next", "back"], np.array([False, False, False]), starts,
                  [NO_ROUTE] * 3, goals, [0.0, 1.0, 2.0])  # fmt: skip
    assert single.must_hold.tolist() == [False, True, True]


def test_a_robot_joins_a_convoy_under_way_and_never_one_coming_the_other_way() -> None:
    east = ZonePass("aisle", (-1.0, 0.0), (1.0, 0.0))
    follows = gate([CONVOY], {"aisle": {"lead": east}}, ["next"], np.array([False]),
                   poses((-5.0, 0.0)), [NO_ROUTE], poses((5.0, 0.0)), [0.0])  # fmt: skip
    assert not follows.must_hold.any()
    meets = gate([CONVOY], {"aisle": {"lead": east}}, ["back"], np.array([False]),
                 poses((5.0, 0.0)), [NO_ROUTE], poses((-5.0, 0.0)), [0.0])  # fmt: skip
    assert meets.must_hold.tolist() == [True]
    standing = gate([CONVOY], {"aisle": {"lost": None}}, ["next"], np.array([False]),
                    poses((-5.0, 0.0)), [NO_ROUTE], poses((5.0, 0.0)), [0.0])  # fmt: skip
    assert standing.must_hold.tolist() == [True]  # a robot standing in it goes no way


def test_a_convoys_leader_at_the_far_mouth_goes_on_whichever_way_it_leaves() -> None:
    """The corridor, perfect robots: the leader of a westbound convoy stood at the west
    mouth, inside the zone, its way out bending south to its bay (a pass 67 degrees off the
    convoy's), its follower 0.8 m behind it in the zone; held for the zone by the follower
    "going the other way", it blocked the follower's way out for 280 s. Standing in the zone,
    it goes on, out of it; the same way from outside still waits for the convoy."""
    west = ZonePass("aisle", (1.0, 0.0), (-1.0, 0.0))
    holders = {"aisle": {"leader": west, "follower": west}}
    out_south = [np.array([[-0.9, -0.6]])]
    leaves = gate([CONVOY], holders, ["leader"], np.array([False]), poses((-0.9, 0.1)),
                  out_south, poses((-3.0, -3.0)), [0.0])  # fmt: skip
    assert not leaves.must_hold.any()
    assert [p.zone for p in leaves.granted[0]] == ["aisle"]
    assert leaves.granted[0][0].entry == (-0.9, 0.1)  # its pass starts where it stands
    outside = gate([CONVOY], {"aisle": {"follower": west}}, ["other"], np.array([False]),
                   poses((-0.9, 1.5)), [np.array([[-0.9, 0.1], [-0.9, -0.6]])],
                   poses((-3.0, -3.0)), [0.0])  # fmt: skip
    assert outside.must_hold.tolist() == [True]
