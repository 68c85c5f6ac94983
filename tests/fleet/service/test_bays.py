"""BayBook: reservations and the free / reserved / occupied state of every bay."""

from __future__ import annotations

import pytest

from fleet.core.site import Bay, Site, Yard
from fleet.core.tasks import BayNotFound, BayTaken, RobotStatus, RobotView, Task, TaskRequest
from fleet.core.wire import Pose
from fleet.service.bays import BayBook

SITE = Site(
    yard=Yard(xmin=-10, xmax=10, ymin=-10, ymax=10),
    bays=[
        Bay(name="A1", pose=Pose(x=0, y=5)),
        Bay(name="C1", pose=Pose(x=5, y=0), group="charging"),
        Bay(name="C2", pose=Pose(x=5, y=3), group="charging"),
    ],
)


def task(task_id: str, bay: str, robot: str | None = None) -> Task:
    request = TaskRequest(goal=SITE.bay(bay).pose, bay=bay)  # type: ignore[union-attr]
    return Task(id=task_id, request=request, robot_id=robot, created_at=0.0, updated_at=0.0)


def robot(rid: str, x: float, y: float) -> RobotView:
    return RobotView(robot_id=rid, status=RobotStatus.IDLE, pose=Pose(x=x, y=y), last_seen=0.0)


def test_reservation_states_and_group_candidates() -> None:
    book = BayBook(SITE)
    t1 = task("t1", "C1", robot="r1")
    book.check(t1)
    book.hold(t1)
    with pytest.raises(BayTaken, match="bay C1 is taken by task t1"):
        book.check(task("t2", "C1"))
    assert [b.name for b in book.candidates(None, "charging")] == ["C2"]
    states = {
        s.bay.name: s for s in book.states({"t1": t1}, [robot("r1", 4, 0), robot("r2", 0.3, 5.2)])
    }
    assert (states["C1"].status, states["C1"].task_id, states["C1"].robot_id) == (
        "reserved",
        "t1",
        "r1",
    )
    assert (states["A1"].status, states["A1"].robot_id) == ("occupied", "r2")
    assert states["C2"].status == "free"
    book.release("t2")  # not its holder: nothing changes
    assert book.holder("C1") == "t1"
    book.release(t1.id)
    assert book.holder("C1") is None and len(book) == 0
    assert [b.name for b in book.candidates(None, "charging")] == ["C1", "C2"]


def test_unknown_names_and_no_site() -> None:
    with pytest.raises(BayNotFound, match="bay Z not found"):
        BayBook(SITE).candidates("Z", None)
    with pytest.raises(BayNotFound, match="no site map"):
        BayBook(None).candidates("A1", None)
    assert BayBook(None).states({}, []) == []
