"""FailoverService on a real PostgreSQL server (robots on in-memory buses): the standby
follows the store by LISTEN and refuses writes; the leader's messages carry its term and a
deposed leader publishes nothing."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
from support import wait_for

from fleet.core.planner import Plan, PlanningSnapshot, plan
from fleet.core.tasks import FleetEvent, TaskEvent, TaskRequest
from fleet.core.wire import ControlAction, ParkAssignment, Pose, RobotMode, RobotState
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.planner_worker import PlanFunction
from fleet.service.roles import NotLeader, Role
from fleet.service.standby import FailoverService
from fleet.service.store_postgres import PostgresTaskStore


class Node:
    """One FailoverService with its own store and the buses it was given, newest last."""

    def __init__(self, dsn: str, name: str, planner: PlanFunction | None = None) -> None:
        self.store = PostgresTaskStore(dsn)
        self.buses: list[MemoryBus] = []
        self.events: list[FleetEvent] = []
        self.lock = threading.Lock()
        self.service = FailoverService(
            Settings(leader_lease_s=2.0, leader_poll_s=0.02), self.store, self._bus,
            name=name, address=f"http://{name}", planner=planner,
        )  # fmt: skip
        self.service.add_listener(self._event)

    def _bus(self) -> MemoryBus:
        bus = MemoryBus()
        self.buses.append(bus)
        return bus

    def _event(self, event: FleetEvent) -> None:
        with self.lock:
            self.events.append(event)

    def task_events(self, task_id: str) -> list[TaskEvent]:
        with self.lock:
            return [e for e in self.events if isinstance(e, TaskEvent) and e.task.id == task_id]

    def close(self) -> None:
        self.service.close()
        self.store.close()


@pytest.fixture
def nodes(postgres_dsn: str) -> Iterator[tuple[Node, Node]]:
    a = Node(postgres_dsn, "a")
    a.service.start()
    wait_for(lambda: a.service.failover_status().role is Role.LEADER, 30, "a leading")
    b = Node(postgres_dsn, "b")
    b.service.start()
    try:
        yield a, b
    finally:
        b.close()
        a.close()


def test_the_standby_follows_the_store_and_refuses_writes_naming_the_leader(
    nodes: tuple[Node, Node],
) -> None:
    leader, standby = nodes
    wait_for(lambda: standby.service.failover_status().leader == "http://a", 30, "leader seen")
    with pytest.raises(NotLeader, match="the leader is http://a"):
        standby.service.submit(TaskRequest(goal=Pose(x=1.0, y=1.0)))
    with pytest.raises(NotLeader):
        standby.service.control(ControlAction.ESTOP)
    task = leader.service.submit(TaskRequest(goal=Pose(x=1.0, y=1.0)))
    wait_for(lambda: standby.task_events(task.id) != [], 30, "the change followed by LISTEN")
    assert standby.service.task(task.id).id == task.id
    assert [t.id for t in standby.service.tasks()] == [task.id]
    assert standby.service.robots() == [] and standby.service.failover_status().term == 1


def test_the_leader_stamps_its_term_and_the_successor_takes_over_the_task(
    nodes: tuple[Node, Node],
) -> None:
    leader, standby = nodes
    bus = leader.buses[-1]
    bus.robot_alive("r1")
    bus.deliver_state(RobotState(robot_id="r1", seq=1, stamp=0.0, pose=Pose(x=0.0, y=0.0)))
    task = leader.service.submit(TaskRequest(goal=Pose(x=3.0, y=0.0)))
    wait_for(lambda: any(isinstance(m, ParkAssignment) for m in bus.assignments), 60, "assigned")
    assert {m.term for m in bus.assignments} == {1}
    leader.service.leadership.close()  # steps down: the service stops, its bus goes quiet
    sent = len(bus.assignments)
    wait_for(lambda: standby.service.leading is not None, 30, "take-over")
    assert bus.closed and len(bus.assignments) == sent
    successor = standby.buses[-1]
    successor.robot_alive("r1")
    successor.deliver_state(  # the robot has not acknowledged: the new leader re-sends
        RobotState(robot_id="r1", seq=2, stamp=0.0, pose=Pose(x=0.0, y=0.0), mode=RobotMode.IDLE)
    )
    wait_for(
        lambda: any(m.task_id == task.id for m in successor.assignments), 60, "re-sent by term 2"
    )
    assert {m.term for m in successor.assignments} == {2}
    assert standby.service.counters["tasks_recovered"] == 1


class GatedNode(Node):
    """A node whose take-over waits at its bus until ``gate`` is set (``building`` is set
    then): the time a real take-over spends rebuilding the ledger from the store."""

    def __init__(self, dsn: str, name: str) -> None:
        self.gate = threading.Event()
        self.building = threading.Event()
        super().__init__(dsn, name)

    def _bus(self) -> MemoryBus:
        self.building.set()
        self.gate.wait()
        return super()._bus()


def test_an_elected_process_says_leader_only_once_its_service_leads(postgres_dsn: str) -> None:
    # /healthz said "leader" from the election on, before the service existed: a client
    # that waited for the role then read counters the service had yet to count
    # (tasks_recovered) and had its writes refused by the leader itself.
    node = GatedNode(postgres_dsn, "a")
    node.service.start()
    try:
        wait_for(node.building.is_set, 30, "the take-over under way")
        assert node.service.leadership.role is Role.LEADER  # elected ...
        assert node.service.failover_status().role is Role.STANDBY  # ... not yet leading
        with pytest.raises(NotLeader):
            node.service.submit(TaskRequest(goal=Pose(x=1.0, y=1.0)))
        node.gate.set()
        wait_for(lambda: node.service.failover_status().role is Role.LEADER, 30, "leading")
        assert node.service.counters["tasks_recovered"] == 0
        assert node.service.submit(TaskRequest(goal=Pose(x=1.0, y=1.0))).id
    finally:
        node.gate.set()
        node.close()


def test_the_leader_plans_with_the_plan_function_it_was_given(postgres_dsn: str) -> None:
    # open_failover gives it the planner's own process when Settings.planner_process is on
    planned: list[int] = []

    def counting(snapshot: PlanningSnapshot) -> Plan:
        planned.append(len(snapshot.robots))
        return plan(snapshot)

    node = Node(postgres_dsn, "a", counting)
    node.service.start()
    try:
        wait_for(lambda: node.service.failover_status().role is Role.LEADER, 30, "leading")
        bus = node.buses[-1]
        bus.robot_alive("r1")
        bus.deliver_state(RobotState(robot_id="r1", seq=1, stamp=0.0, pose=Pose(x=0.0, y=0.0)))
        node.service.submit(TaskRequest(goal=Pose(x=3.0, y=0.0)))
        wait_for(lambda: any(isinstance(m, ParkAssignment) for m in bus.assignments), 60, "plan")
        assert 1 in planned
    finally:
        node.close()
