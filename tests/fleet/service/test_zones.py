"""Single-robot zones held by the service: the zone book, the ledger granting them with a
plan's decisions and taking them back, and the whole service sending one robot through a
narrow passage while the other waits for it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from fleet.core.planner import TaskDecision
from fleet.core.site import Wall
from fleet.core.tasks import GoalRejected, Task, TaskRequest, TaskStatus
from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.core.zones import ZonePass, ZoneShape
from fleet.service.ledger import LedgerConfig, Outcome, TaskLedger
from fleet.service.zones import ZoneBook
from tests.fleet.service.conftest import Fleet, req

GATE = ZoneShape("gate", ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)))
WALL = 1.7e9


EAST = ZonePass("gate", (-1.0, 0.0), (1.0, 0.0))
WEST = ZonePass("gate", (1.0, 0.0), (-1.0, 0.0))


def test_a_robot_takes_a_free_zone_it_stands_in_and_gives_it_back_once_out_and_past() -> None:
    book = ZoneBook([GATE])
    assert book.can_take("r1", [EAST]) and book.take("r1", [EAST])
    assert not book.can_take("r2", [EAST]) and book.can_take("r1", [EAST])
    assert book.can_take("r2", [ZonePass("gone", (0.0, 0.0), (1.0, 0.0))])  # no such zone
    ahead = [(-3.0, 0.0), (3.0, 0.0)]
    assert not book.observe("r1", -3.0, 0.0, lambda: ahead)  # on its way to the zone: kept
    assert not book.observe("r1", 0.0, 0.0, lambda: [(0.0, 0.0), (3.0, 0.0)])  # in it: kept
    assert book.observe("r1", 2.0, 0.0, lambda: [(2.0, 0.0), (3.0, 0.0)])  # out and past
    assert book.holding("gate") == () and len(book) == 0
    assert book.observe("r2", 0.5, 0.0, None)  # a robot standing in it takes it
    assert book.holding("gate") == ("r2",)
    assert not book.observe("r2", 0.5, 0.2, None)  # standing in it: keeps it, task or not
    assert book.release_robot("r2") and book.holding("gate") == ()


def test_a_robot_whose_way_runs_through_a_post_keeps_its_zone() -> None:
    """The law and Eq. (27) may swing a robot wide of a passage's mouth, to where the
    straight line to its goal passes through a post (case III with four robots: the zone
    went to a robot coming the other way, and both stood at the mouth for the rest of the
    run). That line is no path: the robot keeps the zone until its way is clear."""
    book = ZoneBook()
    book.set_zones([GATE], [((0.75, 2.5), (0.75, 2.5), 0.3)])
    book.take("r1", [EAST])
    goal = (3.0, 3.0)
    assert not GATE.entered_by([(-1.5, 2.0), goal])  # its straight way misses the zone...
    assert not book.observe("r1", -1.5, 2.0, lambda: [(-1.5, 2.0), goal])  # ...through a post
    assert book.holding("gate") == ("r1",) and not book.can_take("r2", [WEST])
    assert book.observe("r1", 2.0, 1.5, lambda: [(2.0, 1.5), goal])  # a clear way: given back
    assert book.holding("gate") == ()


def test_a_convoy_zone_is_held_by_robots_going_one_way_only() -> None:
    book = ZoneBook([ZoneShape("gate", GATE.outline, convoys=True)])
    assert book.take("r1", [EAST])
    assert book.can_take("r2", [EAST]) and not book.can_take("r3", [WEST])
    book.take("r2", [EAST])
    assert book.holding("gate") == ("r1", "r2")
    assert book.observe("r1", 3.0, 0.0, lambda: [(3.0, 0.0), (4.0, 0.0)])
    assert book.holding("gate") == ("r2",) and not book.can_take("r3", [WEST])
    book.release_robot("r2")
    assert book.can_take("r3", [WEST])


def test_a_robot_standing_in_a_zone_another_holds_holds_it_too_and_may_go_on() -> None:
    """A robot in a zone it was not granted (swung in by a stuck recovery, lost on its way)
    holds it too, standing (pass None): it may go on, out of it, whoever else holds it;
    nobody may join it; it gives the zone back once out and past."""
    book = ZoneBook([ZoneShape("gate", GATE.outline, convoys=True)])
    assert book.take("holder", [WEST])
    assert not book.can_take("inside", [EAST])
    assert book.observe("inside", 0.2, 0.3, lambda: [(0.2, 0.3), (6.0, 0.0)])
    assert book.holding("gate") == ("holder", "inside")
    assert book.can_take("inside", [EAST])  # it goes on, out of the zone
    assert not book.can_take("third", [WEST])  # nobody joins a robot standing in it
    assert book.observe("inside", 3.0, 0.0, lambda: [(3.0, 0.0), (6.0, 0.0)])
    assert book.holding("gate") == ("holder",)


def test_a_holder_standing_in_a_zone_may_go_on_whichever_way_it_leaves() -> None:
    """A convoy's leader standing at the far mouth, its follower behind it: a plan that
    sends it out of the zone off the convoy's direction is applied (held there, it would
    block the follower for good); out of the zone, the convoy rule holds again."""
    book = ZoneBook([ZoneShape("gate", GATE.outline, convoys=True)])
    assert book.take("leader", [WEST]) and book.take("follower", [WEST])
    south = ZonePass("gate", (-0.9, 0.1), (-0.9, -1.0))
    assert not book.can_take("leader", [south])  # not yet seen in the zone
    book.observe("leader", -0.9, 0.1, lambda: [(-0.9, 0.1), (-0.9, -3.0)])
    assert book.can_take("leader", [south])
    assert not book.can_take("third", [south])
    book.observe("leader", -0.9, -1.5, lambda: [(-0.9, -1.5), (-0.9, -3.0)])
    assert book.holding("gate") == ("follower",) and not book.can_take("leader", [south])
    book.observe("leader", -0.9, 0.1, lambda: [(-0.9, 0.1), (-0.9, -3.0)])
    book.release_robot("leader")
    assert not book.can_take("leader", [south])  # removed: nothing of it is remembered


def test_zones_that_are_gone_lose_their_holders() -> None:
    book = ZoneBook([GATE])
    book.take("r1", [EAST])
    book.set_zones([])
    assert book.holders() == {} and book.held_by("r1") == frozenset()


def _ledger() -> TaskLedger:
    ledger = TaskLedger(LedgerConfig(task_timeout_s=30.0, resend_interval_s=0.2, control_hz=50.0))
    ledger.zones.set_zones([GATE])
    return ledger


def _task(task_id: str, x: float) -> Task:
    return Task(
        id=task_id, request=TaskRequest(goal=Pose(x=x, y=0.0)), created_at=WALL, updated_at=WALL
    )


def _apply(ledger: TaskLedger, d: TaskDecision) -> Outcome:
    outcome, _ = ledger.apply(
        d, robot_available=True, plan_safe=True, origin_seq=None, now=0.0, wall=WALL
    )
    return outcome


def _state(rid: str, task_id: str | None, x: float, seq: int, **kw: Any) -> RobotState:
    return RobotState(
        robot_id=rid, seq=seq, stamp=0.0, pose=Pose(x=x, y=0.0), mode=RobotMode.DRIVING,
        task_id=task_id, revision=1, **kw,
    )  # fmt: skip


def test_the_ledger_grants_a_decisions_zones_refuses_them_to_another_and_frees_them() -> None:
    ledger = _ledger()
    ledger.add(_task("t1", 5.0))
    ledger.add(_task("t2", -5.0))
    assert _apply(ledger, TaskDecision("t1", "r1", "assign", "cw", zones=(EAST,))) is (
        Outcome.APPLIED
    )
    assert ledger.zones.holding("gate") == ("r1",)
    # a plan made before r1 took it, starting r2 through the same zone: stale, not sent
    assert _apply(ledger, TaskDecision("t2", "r2", "assign", "cw", zones=(WEST,))) is (
        Outcome.STALE
    )
    assert ledger.active["t2"].status is TaskStatus.QUEUED
    version = ledger.version
    seen = ledger.observe(_state("r1", "t1", -3.0, 1), now=0.0, wall=WALL)
    assert not seen.zones_changed  # on its way to the zone
    seen = ledger.observe(_state("r1", "t1", 3.0, 2), now=0.1, wall=WALL)
    assert seen.zones_changed and ledger.zones.holding("gate") == ()
    assert ledger.version > version  # a plan made before is stale


def test_a_robot_removed_gives_its_zones_back() -> None:
    ledger = _ledger()
    ledger.observe(_state("r9", None, 0.0, 1), now=0.0, wall=WALL)  # lost in the zone
    assert ledger.zones.holding("gate") == ("r9",)
    ledger.robot_removed("r9", WALL)
    assert ledger.zones.holding("gate") == ()


def test_the_service_sends_one_robot_through_a_narrow_passage_and_the_other_after_it() -> None:
    """The real planner: a 1.2 m corridor between two rooms (found as a passage), a robot
    in each room bound for the other; one drives, the other waits naming the passage; once
    the first has come out at the far end, the passage is given back and a plan starts the
    second through it."""
    corridor = Wall(
        points=[(-10, 5), (-4, 5), (-4, 0.6), (4, 0.6), (4, 5), (10, 5), (10, -5), (4, -5),
                (4, -0.6), (-4, -0.6), (-4, -5), (-10, -5)],
        closed=True, body=0.05,
    ).segments()  # fmt: skip
    f = Fleet(task_timeout_s=600.0, yard=(-11.0, 11.0, -6.0, 6.0))
    try:
        f.service.set_obstacles(corridor)
        (passage,) = f.service.zones()
        assert passage.zone.name == "passage-1" and passage.zone.found and passage.zone.convoys
        f.join("w", -7.0, 0.0)
        f.join("e", 7.0, 0.0)
        west = f.service.submit(req(7.0, 2.5, robot="w"))
        east = f.service.submit(TaskRequest(goal=Pose(x=-7.0, y=-2.5, theta=math.pi), robot_id="e"))
        f.service.tick()
        goes, waits = sorted(
            (f.service.task(west.id), f.service.task(east.id)), key=lambda t: t.hold
        )
        assert not goes.hold and waits.hold and waits.status is TaskStatus.WAITING
        assert waits.reason == (
            f"waiting for single-robot zone passage-1 (held by {goes.robot_id} going the other way)"
        )
        (passage,) = f.service.zones()
        assert passage.robot_ids == (goes.robot_id,) and passage.task_ids == (goes.id,)
        # the first robot drives through and comes out in the other room
        assert goes.robot_id is not None and waits.robot_id is not None
        side = 1.0 if goes.robot_id == "w" else -1.0
        for x in (-5.0, -2.0, 2.0, 5.0, 6.0):
            f.robot(goes.robot_id, side * x, 0.0, mode=RobotMode.DRIVING, task_id=goes.id,
                    revision=goes.revision)  # fmt: skip
            f.clock.advance(0.5)
            f.service.tick()
        (passage,) = f.service.zones()
        assert passage.robot_ids == (waits.robot_id,)  # given back, and granted to the next
        resumed = f.service.task(waits.id)
        assert not resumed.hold and resumed.revision > waits.revision
        last = [p for p in f.parks(waits.robot_id) if p.task_id == waits.id][-1]
        assert not last.hold and last.revision == resumed.revision
    finally:
        f.service.close()


def test_a_goal_in_a_site_maps_zone_is_refused_naming_it(tmp_path: Path) -> None:
    site = tmp_path / "site.toml"
    site.write_text(
        "[yard]\nxmin = -10.0\nxmax = 10.0\nymin = -10.0\nymax = 10.0\n"
        '[[zones]]\nname = "gate"\nrect = { xmin = -1.0, xmax = 1.0, ymin = -1.0, ymax = 1.0 }\n'
    )
    f = Fleet(site_file=site)
    try:
        assert [z.zone.name for z in f.service.zones()] == ["gate"]
        f.join("r1", -5.0, 5.0)
        with pytest.raises(GoalRejected, match="inside the single-robot zone gate"):
            f.service.submit(req(0.0, 0.0))
        with pytest.raises(GoalRejected, match=r"is 0\.10 m from the single-robot zone gate"):
            f.service.submit(req(0.0, 1.1))  # the parked body would reach into it
        f.service.submit(req(0.0, 2.0))
    finally:
        f.service.close()


def test_a_robot_standing_aside_for_the_zone_it_waits_on_makes_a_plan_made_before_stale() -> None:
    """r2 waits for the gate r1 holds and holds r1 off: it stands aside (the others are
    routed round it), a change the plan depends on -- once."""
    ledger = _ledger()
    ledger.add(_task("t1", 5.0))
    ledger.add(_task("t2", -5.0))
    assert _apply(ledger, TaskDecision("t1", "r1", "assign", "cw", zones=(EAST,))) is (
        Outcome.APPLIED
    )
    waits = TaskDecision("t2", "r2", "assign", "cw", hold=True, waits_for="gate")
    assert _apply(ledger, waits) is Outcome.APPLIED
    version = ledger.version
    assert ledger.stands_aside(ledger.active["t2"], "r1")
    assert ledger.version > version  # a plan made before is stale
    version = ledger.version
    assert not ledger.stands_aside(ledger.active["t2"], "r1")  # already aside
    assert ledger.version == version
