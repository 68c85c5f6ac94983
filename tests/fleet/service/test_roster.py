"""The roster: states, liveliness, the parked grid, retention and removal (pure)."""

from __future__ import annotations

from fleet.core.tasks import RobotStatus
from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.service.roster import Roster


def state(
    rid: str, x: float, mode: RobotMode = RobotMode.IDLE, task: str | None = None
) -> RobotState:
    return RobotState(
        robot_id=rid, seq=1, stamp=0.0, pose=Pose(x=x, y=0.0), mode=mode, task_id=task
    )


def test_update_reports_status_and_task_changes_only() -> None:
    roster = Roster()
    _, changed = roster.update(state("r1", 0.0), now=1.0, wall=100.0)
    assert changed
    _, changed = roster.update(state("r1", 0.1), now=1.1, wall=100.1)
    assert not changed  # pose only
    _, changed = roster.update(state("r1", 0.2, RobotMode.DRIVING, "t1"), now=1.2, wall=100.2)
    assert changed
    _, changed = roster.update(state("r1", 0.3, RobotMode.DRIVING, "t2"), now=1.3, wall=100.3)
    assert changed
    view = roster.view("r1")
    assert view is not None and view.status is RobotStatus.DRIVING and view.last_seen == 100.3


def test_lost_robots_stay_lost_until_a_new_token_and_stay_obstacles() -> None:
    roster = Roster(parked_cell=1.0)
    roster.alive("r1", wall=0.0)
    roster.update(state("r1", 2.0, RobotMode.DRIVING), now=0.0, wall=0.0)
    assert roster.parked_near(2.0, 0.0, 1.0) == []
    roster.gone("r1", now=1.0)
    assert roster.is_lost("r1")
    (parked,) = roster.parked_near(2.5, 0.0, 1.0)
    assert parked.robot_id == "r1" and parked.what == "lost robot r1"
    roster.update(state("r1", 5.0, RobotMode.DRIVING), now=2.0, wall=0.0)  # late state
    view = roster.view("r1")
    assert view is not None and view.status is RobotStatus.LOST
    assert roster.parked_near(2.0, 0.0, 1.0) == []  # moved in the grid with its pose
    assert [p.robot_id for p in roster.parked_near(5.0, 0.0, 1.0)] == ["r1"]
    roster.alive("r1", wall=0.0)
    assert not roster.is_lost("r1") and roster.parked_near(5.0, 0.0, 1.0) == []


def test_lost_and_tokenless_silent_robots_expire_after_the_retention_time() -> None:
    roster = Roster()
    roster.alive("alive", wall=0.0)
    roster.update(state("alive", 0.0), now=0.0, wall=0.0)
    roster.alive("lost", wall=0.0)
    roster.gone("lost", now=10.0)
    roster.update(state("silent", 3.0), now=5.0, wall=0.0)  # states, never a token
    assert roster.expired(now=14.9, retention_s=10.0) == []
    assert roster.expired(now=15.0, retention_s=10.0) == ["silent"]
    assert sorted(roster.expired(now=20.0, retention_s=10.0)) == ["lost", "silent"]
    roster.update(state("silent", 3.0), now=19.0, wall=0.0)  # it spoke again: not yet
    assert roster.expired(now=20.0, retention_s=10.0) == ["lost"]


def test_removing_a_robot_forgets_everything_about_it() -> None:
    roster = Roster()
    roster.alive("r1", wall=0.0)
    roster.update(state("r1", 1.0, RobotMode.ARRIVED), now=0.0, wall=0.0)
    roster.gone("r1", now=1.0)
    assert roster.sizes() == {"robots": 1, "parked_robots": 1}
    assert roster.remove("r1") is not None
    assert roster.sizes() == {"robots": 0, "parked_robots": 0}
    assert roster.expired(now=1e9, retention_s=1.0) == []
    assert not roster.known("r1") and roster.view("r1") is None and roster.views() == []
    assert roster.remove("r1") is None


def test_version_rises_with_what_a_plan_depends_on_and_not_with_poses() -> None:
    roster = Roster()
    seen = [roster.version]

    def rose() -> bool:
        seen.append(roster.version)
        return seen[-1] > seen[-2]

    roster.alive("r1", wall=0.0)
    assert rose()
    roster.update(state("r1", 0.0), now=1.0, wall=1.0)
    assert rose()  # first state
    roster.update(state("r1", 0.5), now=1.1, wall=1.1)
    assert not rose()  # a pose only
    roster.update(state("r1", 0.6, RobotMode.DRIVING, "t1"), now=1.2, wall=1.2)
    assert rose()  # status and task
    roster.set_in_service("r1", False)
    assert rose()
    roster.set_in_service("r1", False)
    assert not rose()  # no change
    roster.gone("r1", now=2.0)
    assert rose()
    roster.remove("r1")
    assert rose()
    roster.remove("r1")
    assert not rose()  # unknown: nothing removed
