"""Operator control in the fleet service: commands published, tasks held, e-stops re-sent."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from fleet.core.tasks import GoalRejected, RobotNotFound, Task, TaskConflict, TaskStatus
from fleet.core.wire import ControlAction, ControlCommand, Hold, Pose, RobotMode, RobotState
from fleet.service.control_desk import RESEND_S, ControlDesk, ControlState
from fleet.service.ledger import RELEASED_REASON
from fleet.service.store import MemoryTaskStore, SqliteTaskStore
from tests.fleet.service.conftest import Fleet, ScriptedPlanner, assign_queued, req


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
    desk = ControlDesk()
    sent = [desk.command(ControlAction.PAUSE, "r1", None, 1000.0)]
    assert desk.hold("r1").paused and not desk.hold("r2").paused
    sent.append(desk.command(ControlAction.ESTOP, None, None, 1000.0))
    assert desk.state().robots == {} and desk.hold("r1") == Hold(paused=False, estop=True)
    seqs = [m.seq for m in sent]
    assert seqs == sorted(set(seqs))  # strictly increasing, even with a frozen clock
    assert all(m.issuer == "fleet-service" for m in sent)


def test_only_restrictive_commands_are_resent_and_not_too_often() -> None:
    desk = ControlDesk()
    now, wall = 0.0, 1000.0
    sent: list[ControlCommand] = []

    def check(mode: RobotMode) -> None:
        state = RobotState(robot_id="r1", seq=1, stamp=1.0, pose=Pose(x=0, y=0), mode=mode)
        again = desk.check(state, now, wall)
        if again is not None:
            sent.append(again)

    check(RobotMode.DRIVING)
    assert sent == []  # nothing asked: nothing re-sent
    sent.append(desk.command(ControlAction.ESTOP, None, "drill", wall))
    check(RobotMode.DRIVING)  # a robot that missed it (or restarted)
    check(RobotMode.DRIVING)  # too soon for another
    assert [(m.command, m.robot_id, m.reason) for m in sent[1:]] == [
        (ControlAction.ESTOP, "r1", "drill")
    ]
    now += RESEND_S
    check(RobotMode.ESTOP)  # obeys: nothing
    sent.append(desk.command(ControlAction.RELEASE, None, None, wall))
    check(RobotMode.ESTOP)  # e-stopped by someone else: never released by us
    assert [m.command for m in sent] == [
        ControlAction.ESTOP,
        ControlAction.ESTOP,
        ControlAction.RELEASE,
    ]
    desk.forget("r1")
    desk.restore(ControlState(Hold(estop=True), {}))  # as a previous run left it
    check(RobotMode.IDLE)
    assert sent[-1].command is ControlAction.ESTOP and sent[-1].robot_id == "r1"


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
    held = fleet.service.task(task.id)
    assert (held.status, held.hold, held.revision) == (TaskStatus.WAITING, True, 1)
    assert fleet.parks("r1")[-1].hold  # sent: after the release it stands until a plan
    assert fleet.service.task(other.id).status is TaskStatus.QUEUED  # nobody free to take it
    fleet.service.control(ControlAction.RELEASE)
    assert fleet.service.task(task.id).hold  # the release itself starts nothing
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.WAITING, task_id=task.id, revision=1)
    fleet.robot("r2", 5.0, 5.0, mode=RobotMode.IDLE)
    fleet.service.tick()
    assert fleet.service.task(other.id).status is TaskStatus.ASSIGNED
    resumed = fleet.parks("r1")[-1]  # the plan after the release resumed it
    assert (resumed.task_id, resumed.revision, resumed.hold) == (task.id, 2, False)
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


def drive_one_task(fleet: Fleet) -> Task:
    """Robot r1 joins, takes a task and drives it."""
    fleet.join("r1", 0.0, 0.0)
    task = fleet.service.submit(req(3.0, 0.0))
    fleet.service.tick()
    fleet.robot("r1", 0.1, 0.0, mode=RobotMode.DRIVING, task_id=task.id)
    return task


class BreakingStore(MemoryTaskStore):
    """A store whose writes fail once ``broken`` is set (a full disk)."""

    broken = False

    def save(self, task: Task, event: str) -> None:
        if self.broken:
            raise OSError("disk full")
        super().save(task, event)


def test_an_estop_goes_out_first_even_when_the_holds_cannot_be_stored() -> None:
    store = BreakingStore()
    fleet = Fleet(store=store, task_timeout_s=30.0)
    try:
        drive_one_task(fleet)
        store.broken = True
        fleet.service.control(ControlAction.ESTOP, reason="drill")
        assert [c.command for c in fleet.bus.controls] == [ControlAction.ESTOP]
        assert fleet.service.counters["store_errors"] == 1  # the task's hold, not the e-stop
    finally:
        fleet.service.close()


def test_holds_are_in_the_history_the_plan_and_resent_to_late_joiners() -> None:
    planner = ScriptedPlanner(assign_queued())
    fleet = Fleet(planner=planner, task_timeout_s=30.0)
    try:
        task = drive_one_task(fleet)
        fleet.service.control(ControlAction.PAUSE, reason="lunch")
        assert fleet.service.control_state().fleet == Hold(paused=True)
        fleet.join("r2", 5.0, 5.0)  # joins while the fleet is paused: told at once
        assert [(c.command, c.robot_id) for c in fleet.bus.controls] == [
            (ControlAction.PAUSE, None),
            (ControlAction.PAUSE, "r2"),
        ]
        fleet.service.submit(req(-4.0, 4.0))
        fleet.clock.advance(5.0)
        fleet.service.tick()  # the periodic plan: r1's task stands, r2 takes nothing
        (held,) = [t for t in planner.snapshots[-1].tasks if t.task_id == task.id]
        assert held.hold and not any(r.available for r in planner.snapshots[-1].robots)
        fleet.robot("r1", 0.1, 0.0, mode=RobotMode.PAUSED, task_id=task.id)
        fleet.service.control(ControlAction.RESUME)
        held_reason = "paused by the operator: lunch"
        assert fleet.service.task(task.id).reason == held_reason  # it still reports paused
        fleet.robot("r1", 0.1, 0.0, mode=RobotMode.WAITING, task_id=task.id, revision=1)
        rows = [(event, t.reason) for _, event, t in fleet.service.history(task.id)]
        assert rows[-2:] == [
            ("operator_hold", held_reason),
            ("operator_release", RELEASED_REASON),  # it stands until a plan resumes it
        ]
    finally:
        fleet.service.close()


def test_holds_and_decommissioning_survive_a_restart(tmp_path: Path) -> None:
    store = SqliteTaskStore(tmp_path / "parkfleet.db")
    try:
        first = Fleet(store=store)
        first.join("r1", 0.0, 0.0)
        first.join("r2", 3.0, 3.0)
        first.service.decommission("r1")
        first.service.control(ControlAction.ESTOP, reason="drill")
        first.service.control(ControlAction.PAUSE, "r2", reason="inspection")
        first.service.close()

        second = Fleet(store=store)  # the service restarts on the same database
        state = second.service.control_state()
        assert state.fleet == Hold(estop=True) and state.robots == {"r2": Hold(True, True)}
        second.join("r1", 0.0, 0.0)  # robots report in, e.g. restarted and not e-stopped
        second.join("r2", 3.0, 3.0)
        assert not second.service.robot("r1").in_service
        assert [(c.command, c.robot_id, c.reason) for c in second.bus.controls] == [
            (ControlAction.ESTOP, "r1", "drill"),
            (ControlAction.ESTOP, "r2", "inspection"),
        ]
        second.service.commission("r1")
        second.service.close()
        third = Fleet(store=store)
        third.join("r1", 0.0, 0.0)
        assert third.service.robot("r1").in_service
        third.service.close()
    finally:
        store.close()


def foreign(action: ControlAction, seq: int, robot: str | None = None) -> ControlCommand:
    return ControlCommand(
        command=action, robot_id=robot, issuer="cli-host", seq=seq, stamp=1.0, reason="drill"
    )


def test_commands_of_other_tools_are_taken_up_in_their_order(fleet: Fleet) -> None:
    task = drive_one_task(fleet)
    fleet.bus.deliver_control(foreign(ControlAction.ESTOP, 10))  # parkfleet estop, elsewhere
    assert fleet.service.control_state().fleet == Hold(estop=True)
    why = "emergency stop by the operator: drill (cli-host)"
    assert fleet.service.task(task.id).reason == why
    fleet.join("r2", 5.0, 5.0)  # a late joiner learns the latched e-stop from the service
    assert [(c.command, c.robot_id, c.issuer) for c in fleet.bus.controls] == [
        (ControlAction.ESTOP, "r2", "fleet-service"),
    ]
    fleet.bus.deliver_control(foreign(ControlAction.RELEASE, 12))
    fleet.bus.deliver_control(foreign(ControlAction.ESTOP, 11))  # late copy of an older one
    fleet.bus.deliver_control(fleet.bus.controls[0])  # the service's own, echoed
    assert fleet.service.control_state().fleet == Hold()
    fleet.clock.advance(1.0)
    fleet.robot("r2", 5.0, 5.0)  # not e-stopped: nothing is re-sent any more
    assert len(fleet.bus.controls) == 1
    assert fleet.service.task(task.id).reason == RELEASED_REASON  # until a plan resumes it
    assert fleet.service.counters["control_adopted"] == 2
