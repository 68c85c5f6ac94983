"""Operator control in the fleet service: commands published, tasks held, e-stops re-sent."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from fleet.core.tasks import GoalRejected, RobotNotFound, TaskConflict, TaskStatus
from fleet.core.wire import ControlAction, ControlCommand, Hold, Pose, RobotMode, RobotState
from fleet.service.control_desk import RESEND_S, ControlDesk
from tests.fleet.service.test_service import Fleet, req


@pytest.fixture
def fleet() -> Iterator[Fleet]:
    f = Fleet(task_timeout_s=30.0)
    yield f
    f.service.close()


def test_hold_follows_the_commands() -> None:
    hold = Hold().apply(ControlAction.PAUSE).apply(ControlAction.ESTOP)
    assert hold == Hold(paused=True, estop=True) and hold.restrictive is ControlAction.ESTOP
    hold = hold.apply(ControlAction.RELEASE)
    assert hold.restrictive is ControlAction.PAUSE
    assert hold.apply(ControlAction.RESUME).restrictive is None


def test_a_fleet_wide_command_replaces_the_robots_own() -> None:
    sent: list[ControlCommand] = []
    desk = ControlDesk(sent.append, clock=lambda: 1000.0)
    desk.command(ControlAction.PAUSE, "r1")
    assert desk.hold("r1").paused and not desk.hold("r2").paused
    desk.command(ControlAction.ESTOP)
    assert desk.robots() == {} and desk.hold("r1") == Hold(paused=False, estop=True)
    seqs = [m.seq for m in sent]
    assert seqs == sorted(set(seqs))  # strictly increasing, even with a frozen clock


def test_only_restrictive_commands_are_resent_and_not_too_often() -> None:
    sent: list[ControlCommand] = []
    now = [0.0]
    desk = ControlDesk(sent.append, clock=lambda: 1000.0, monotonic=lambda: now[0])

    def state(mode: RobotMode) -> RobotState:
        return RobotState(robot_id="r1", seq=1, stamp=1.0, pose=Pose(x=0, y=0), mode=mode)

    desk.check(state(RobotMode.DRIVING))
    assert sent == []  # nothing asked: nothing re-sent
    desk.command(ControlAction.ESTOP, reason="drill")
    desk.check(state(RobotMode.DRIVING))  # a robot that missed it (or restarted)
    desk.check(state(RobotMode.DRIVING))  # too soon for another
    assert [(m.command, m.robot_id, m.reason) for m in sent[1:]] == [
        (ControlAction.ESTOP, "r1", "drill")
    ]
    now[0] += RESEND_S
    desk.check(state(RobotMode.ESTOP))  # obeys: nothing
    desk.command(ControlAction.RELEASE)
    desk.check(state(RobotMode.ESTOP))  # e-stopped by someone else: never released by us
    assert [m.command for m in sent] == [
        ControlAction.ESTOP,
        ControlAction.ESTOP,
        ControlAction.RELEASE,
    ]
    assert desk.resent == 1


def test_estopped_robots_keep_their_tasks_without_timeout_and_take_no_new_ones(
    fleet: Fleet,
) -> None:
    fleet.join("r1", 0.0, 0.0)
    fleet.join("r2", 5.0, 5.0)
    task = fleet.service.submit(req(3.0, 0.0, robot="r1"))
    fleet.service.tick()
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    fleet.service.control(ControlAction.ESTOP, reason="drill")
    assert fleet.bus.controls[-1].robot_id is None
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.ESTOP, task_id=task.id)
    fleet.robot("r2", 5.0, 5.0, mode=RobotMode.ESTOP)
    other = fleet.service.submit(req(-4.0, -4.0))
    for _ in range(5):
        fleet.clock.advance(20.0)  # 100 s > task_timeout_s
        fleet.service.tick()
    assert fleet.service.task(task.id).status is TaskStatus.DRIVING
    assert fleet.service.task(other.id).status is TaskStatus.QUEUED  # nobody free to take it
    fleet.service.control(ControlAction.RELEASE)
    fleet.robot("r2", 5.0, 5.0, mode=RobotMode.IDLE)
    fleet.service.tick()
    assert fleet.service.task(other.id).status is TaskStatus.ASSIGNED
    assert fleet.service.counters["estops_requested"] == 1


def test_control_of_an_unknown_robot_is_refused(fleet: Fleet) -> None:
    with pytest.raises(RobotNotFound, match="robot ghost not found"):
        fleet.service.control(ControlAction.PAUSE, "ghost")
    assert fleet.bus.controls == []


def test_a_decommissioned_robot_gets_no_task_and_its_task_is_requeued(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    assert fleet.service.task(task.id).robot_id == "r1"
    view = fleet.service.decommission("r1")
    assert view.in_service is False
    requeued = fleet.service.task(task.id)
    assert requeued.status is TaskStatus.QUEUED and requeued.robot_id is None
    assert requeued.reason == "robot r1 decommissioned; requeued"
    assert fleet.cancels("r1")[-1].task_id == task.id  # told to stop
    fleet.robot("r1", 0.2, 0.0, mode=RobotMode.HOLDING, task_id=task.id)
    fleet.service.tick()
    assert fleet.service.task(task.id).status is TaskStatus.QUEUED  # nobody takes it
    with pytest.raises(TaskConflict, match="robot r1 is decommissioned"):
        fleet.service.submit(req(-3.0, 0.0, robot="r1"))
    fleet.service.commission("r1")
    fleet.robot("r1", 0.2, 0.0, mode=RobotMode.IDLE)
    fleet.service.tick()
    assert fleet.service.task(task.id).status is TaskStatus.ASSIGNED


def test_a_lost_decommissioned_robot_no_longer_blocks_goals(fleet: Fleet) -> None:
    fleet.join("r1", 0.0, 0.0)
    fleet.bus.robot_gone("r1")
    with pytest.raises(GoalRejected, match="lost robot r1"):
        fleet.service.submit(req(0.5, 0.0))
    fleet.service.decommission("r1")
    assert fleet.service.submit(req(0.5, 0.0)).status is TaskStatus.QUEUED
