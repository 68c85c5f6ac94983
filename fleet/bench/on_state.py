"""Micro-benchmark of :meth:`fleet.service.FleetService.on_state`, the service's hot path.

Robot agents publish their state at 50 Hz: 1 000 robots are 50 000 states a second into
``on_state``. This bench feeds pre-built ``RobotState`` messages (decoding is the bus's
cost, not the service's) for ``robots`` robots on a grid, round after round, advancing a
fake clock by one control period per round, into a service with an in-memory bus and store
and one listener (as the SSE hub is). Two workloads:

* ``idle`` -- every robot stands idle: pose-only updates;
* ``driving`` -- every robot drives its own task (acknowledged in a warm-up round): the
  task check and the path recording run on every state.

It reports states per CPU second of the calling thread (one core) and microseconds per
state; a robot event goes to the listener at most every 0.1 s per robot, as in service.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from fleet.core.planner import Plan, PlanningSnapshot, TaskDecision
from fleet.core.tasks import FleetEvent, TaskRequest, TaskStatus
from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.clock import FakeClock
from fleet.service.fleet_service import FleetService
from fleet.service.store import MemoryTaskStore

WORKLOADS = ("idle", "driving")
CONTROL_HZ = 50.0
SPACING_M = 5.0  # grid spacing of the robots (their goals stay apart)


@dataclass(frozen=True)
class OnStateRow:
    workload: str
    robots: int
    states: int
    states_per_cpu_s: float
    us_per_state: float
    events: int  # robot and task events the listener received while timed


def _grid(n: int) -> list[tuple[float, float]]:
    side = max(1, math.ceil(math.sqrt(n)))
    half = SPACING_M * (side - 1) / 2
    return [(SPACING_M * (i % side) - half, SPACING_M * (i // side) - half) for i in range(n)]


def _give_named_tasks(snapshot: PlanningSnapshot) -> Plan:
    """Each queued task to the robot it names, with the law it asks for (the bench times
    ``on_state``, not planning: no rollouts)."""
    decisions = tuple(
        TaskDecision(t.task_id, t.named_robot, "assign", "ccw" if t.direction == "ccw" else "cw")
        for t in snapshot.tasks
        if t.status is TaskStatus.QUEUED and t.named_robot is not None
    )
    return Plan(snapshot.version, decisions, True, float("inf"))


def run_on_state(workload: str, robots: int = 1000, rounds: int = 50) -> OnStateRow:
    """Time ``rounds`` states of each of ``robots`` robots through ``on_state``."""
    if workload not in WORKLOADS:
        raise ValueError(f"unknown workload {workload!r}; choose from {', '.join(WORKLOADS)}")
    poses = _grid(robots)
    extent = SPACING_M * math.ceil(math.sqrt(robots)) + 10.0
    settings = Settings(yard=(-extent, extent, -extent, extent), task_timeout_s=1e9)
    clock = FakeClock()
    bus = MemoryBus()
    service = FleetService(settings, bus, MemoryTaskStore(), clock=clock, planner=_give_named_tasks)
    events = 0

    def count(event: FleetEvent) -> None:
        nonlocal events
        events += 1

    service.add_listener(count)
    service.start(background=False)
    try:
        ids = [f"r{i}" for i in range(robots)]
        for rid, (x, y) in zip(ids, poses, strict=True):
            bus.robot_alive(rid)
            bus.deliver_state(RobotState(robot_id=rid, seq=0, stamp=0.0, pose=Pose(x=x, y=y)))
        tasks: dict[str, str] = {}
        if workload == "driving":
            for rid, (x, y) in zip(ids, poses, strict=True):
                request = TaskRequest(goal=Pose(x=x + 2.0, y=y + 2.0), robot_id=rid, direction="cw")
                tasks[rid] = service.submit(request).id
            service.tick()  # assigns every task
        mode = RobotMode.DRIVING if workload == "driving" else RobotMode.IDLE
        frames = [
            [
                RobotState(
                    robot_id=rid,
                    seq=k + 1,
                    stamp=0.0,
                    pose=Pose(x=x + 0.001 * k, y=y),
                    u=0.1 if tasks else 0.0,
                    mode=mode,
                    task_id=tasks.get(rid),
                )
                for rid, (x, y) in zip(ids, poses, strict=True)
            ]
            for k in range(rounds + 1)
        ]
        warm_up, timed = frames[0], frames[1:]
        for state in warm_up:  # acknowledgements (store writes) happen here, untimed
            service.on_state(state)
        events = 0
        on_state, advance, period = service.on_state, clock.advance, 1.0 / CONTROL_HZ
        began = time.thread_time()
        for frame in timed:
            advance(period)
            for state in frame:
                on_state(state)
        cpu = time.thread_time() - began
    finally:
        service.close()
    n = robots * rounds
    return OnStateRow(workload, robots, n, n / cpu, 1e6 * cpu / n, events)


def run_on_state_bench(robots: int = 1000, rounds: int = 50, repeats: int = 3) -> list[OnStateRow]:
    """Both workloads, best of ``repeats`` runs each (the machine is shared)."""
    rows = []
    for workload in WORKLOADS:
        runs = [run_on_state(workload, robots, rounds) for _ in range(repeats)]
        rows.append(max(runs, key=lambda r: r.states_per_cpu_s))
    return rows
