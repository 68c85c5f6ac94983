"""``parkfleet bench fleet``: multi-robot scenarios through the real service over Zenoh.

Each run starts, in this process, a Zenoh router session, a :class:`FleetService` with a
SQLite store and a :class:`ZenohFleetBus`, plus a recorder subscribed to every robot
state; the robots are one ``parkfleet sim`` subprocess (time-scaled, spawned from a JSON
file). Tasks are submitted through :meth:`FleetService.submit` as an API client would.

Scenarios:

* ``swap-N`` -- N robots on a circle of radius 6 m, each parking at the antipodal point
  (start heading: towards the centre turned by -pi/4; goal heading turned by +pi/4);
  tasks name their robot.
* ``yard-sS`` -- 10 robots at random postures in a 10 m x 10 m yard and 10 random goals
  (seed S; starts and goals >= 1.5 m apart); tasks are unnamed, so the optimal assignment
  decides who parks where.
* ``case-III`` -- the paper's comparative case III, (0, 2, 0) -> (0, -2, 0), with its
  Table 8 gains per law and two static obstacles at (+-0.8, 0) (influence radius 1 m,
  K_avoid = 4; the paper gives no coordinates, only the figure).

Policies: ``auto`` (the service's rollout-based choice), ``cw`` and ``ccw`` for every task,
and ``none`` (auto direction with K_avoid = 0: no repulsion from peers or obstacles).

Metrics per run: success rate; collisions (robot pairs whose centres came closer than the
sum of their radii, 2 x 0.2 m); the minimum centre distance between robots (alone: to a
static obstacle's centre) [m]; makespan -- simulated seconds from submission until the
last task is final (robot state sequence numbers / control rate, so a slow CPU does not
inflate it); path ratio -- mean over tasks of distance driven / straight-line distance.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from fleet.core.params import Avoidance, Gains, Tolerance
from fleet.core.tasks import Direction, FleetEvent, TaskEvent, TaskRequest, TaskStatus
from fleet.core.types import Law, Posture
from fleet.core.wire import Keys, Obstacle, Pose, RobotState
from fleet.io.decoder import Decoder
from fleet.io.processes import sim_command, terminate
from fleet.io.settings import Settings, load_settings
from fleet.io.transport import listening_locators, open_session, tcp_endpoint
from fleet.paper.scenarios import SCENARIOS
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from fleet.service.zenoh_bus import ZenohFleetBus

POLICIES: tuple[str, ...] = ("auto", "cw", "ccw", "none")
_LOOSE = Tolerance(position=0.1, heading=0.1)


class FleetBenchRow(BaseModel):
    """One scenario under one policy."""

    scenario: str
    robots: int
    policy: str
    success_rate: float
    collisions: int
    min_separation_m: float
    makespan_s: float
    path_ratio: float


@dataclass(frozen=True)
class FleetScenario:
    name: str
    starts: list[Posture]
    goals: list[Posture]
    named: bool = True
    obstacles: list[Obstacle] = field(default_factory=list)
    law_gains: dict[Law, Gains] | None = None
    tolerance: Tolerance = _LOOSE

    @property
    def robot_ids(self) -> list[str]:
        return [f"b{i + 1}" for i in range(len(self.starts))]


def swap_scenario(n: int, radius: float = 6.0) -> FleetScenario:
    """Antipodal swap of ``n`` robots on a circle of ``radius`` [m]."""
    starts: list[Posture] = []
    goals: list[Posture] = []
    for i in range(n):
        a = 2 * math.pi * i / n
        c, s = radius * math.cos(a), radius * math.sin(a)
        starts.append((c, s, a + math.pi - math.pi / 4))
        goals.append((-c, -s, a + math.pi + math.pi / 4))
    return FleetScenario(name=f"swap-{n}", starts=starts, goals=goals)


def random_yard_scenario(
    n: int, seed: int, half: float = 5.0, spacing: float = 1.5
) -> FleetScenario:
    """``n`` random starts and goals in a ``2 half`` x ``2 half`` m yard (seeded)."""
    rng = np.random.default_rng(seed)
    points: list[tuple[float, float]] = []
    while len(points) < 2 * n:
        x, y = (float(v) for v in rng.uniform(-half, half, size=2))
        if all(math.hypot(x - px, y - py) >= spacing for px, py in points):
            points.append((x, y))
    heads = rng.uniform(-math.pi, math.pi, size=2 * n)
    poses = [(x, y, float(t)) for (x, y), t in zip(points, heads, strict=True)]
    return FleetScenario(name=f"yard-s{seed}", starts=poses[:n], goals=poses[n:], named=False)


def case_iii_scenario() -> FleetScenario:
    """The paper's comparative case III with two static obstacles (Section 6)."""
    case = SCENARIOS["III"]
    return FleetScenario(
        name="case-III",
        starts=[case.start],
        goals=[case.goal],
        obstacles=[Obstacle(x=0.8, y=0.0, radius=1.0), Obstacle(x=-0.8, y=0.0, radius=1.0)],
        law_gains=dict(case.gains),
        tolerance=case.tolerance,
    )


def default_scenarios(quick: bool = False) -> list[FleetScenario]:
    if quick:
        return [
            swap_scenario(2),
            swap_scenario(4),
            random_yard_scenario(10, 1),
            case_iii_scenario(),
        ]
    return [
        *(swap_scenario(n) for n in (2, 4, 8, 16)),
        *(random_yard_scenario(10, seed) for seed in (1, 2)),
        case_iii_scenario(),
    ]


class _Recorder:
    """Every robot's state stream: distance driven, closest approach, sequence numbers."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._decoder = Decoder("bench")
        self.pos: dict[str, tuple[float, float]] = {}
        self.radius: dict[str, float] = {}
        self.seq: dict[str, int] = {}
        self.driven: dict[str, float] = {}
        self.closest: dict[tuple[str, str], float] = {}
        self.recording = False

    def on_sample(self, sample: Any) -> None:
        state = self._decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None:
            return
        rid, p = state.robot_id, (state.pose.x, state.pose.y)
        with self._lock:
            self.seq[rid] = state.seq
            self.radius[rid] = state.radius
            last = self.pos.get(rid)
            self.pos[rid] = p
            if not self.recording:
                return
            if last is not None:
                self.driven[rid] = self.driven.get(rid, 0.0) + math.dist(last, p)
            for other, q in self.pos.items():
                if other != rid:
                    key = (min(rid, other), max(rid, other))
                    d = math.dist(p, q)
                    if d < self.closest.get(key, math.inf):
                        self.closest[key] = d

    def start_recording(self) -> dict[str, int]:
        with self._lock:
            self.recording = True
            return dict(self.seq)

    def snapshot_seq(self) -> dict[str, int]:
        with self._lock:
            return dict(self.seq)


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def run_scenario(
    session: Any,
    endpoint: str,
    scenario: FleetScenario,
    policy: str,
    *,
    fleet_name: str,
    workdir: Path,
    time_scale: float,
    horizon_s: float,
) -> FleetBenchRow:
    """Run one scenario under one policy with a fresh service and fresh sim robots."""
    avoidance = Avoidance(k_avoid=0.0) if policy == "none" else Avoidance()
    settings = load_settings(
        fleet_name=fleet_name,
        task_timeout_s=horizon_s / time_scale + 5.0,
        avoidance=avoidance,
    )
    direction: Direction = "cw" if policy == "cw" else "ccw" if policy == "ccw" else "auto"
    ids = scenario.robot_ids
    spawn = workdir / f"{fleet_name}.json"
    spawn.write_text(
        json.dumps(
            [
                {"id": rid, "x": s[0], "y": s[1], "theta": s[2]}
                for rid, s in zip(ids, scenario.starts, strict=True)
            ]
        )
    )
    keys = Keys(fleet_name)
    recorder = _Recorder()
    store = SqliteTaskStore(workdir / f"{fleet_name}.db")
    service = FleetService(settings, ZenohFleetBus(session, keys), store)
    final_seq: dict[str, dict[str, int]] = {}

    def on_event(event: FleetEvent) -> None:
        if isinstance(event, TaskEvent) and event.task.status.final:
            final_seq[event.task.id] = recorder.snapshot_seq()

    service.add_listener(on_event)
    subscriber = session.declare_subscriber(keys.all_states, recorder.on_sample)
    env = dict(os.environ)
    env["PARKFLEET_FLEET_NAME"] = fleet_name
    env["PARKFLEET_AVOIDANCE__K_AVOID"] = str(avoidance.k_avoid)
    proc = subprocess.Popen(
        sim_command(endpoint, len(ids), time_scale=time_scale, spawn=str(spawn)),
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        service.start()
        service.set_obstacles(scenario.obstacles)
        if not _wait(lambda: len(service.robots()) == len(ids), 30.0):
            raise RuntimeError(f"{scenario.name}: the simulated robots did not come up")
        start_seq = recorder.start_recording()
        tasks = [
            service.submit(
                TaskRequest(
                    goal=Pose(x=g[0], y=g[1], theta=g[2]),
                    robot_id=rid if scenario.named else None,
                    direction=direction,
                    law_gains=scenario.law_gains,
                    tolerance=scenario.tolerance,
                )
            )
            for rid, g in zip(ids, scenario.goals, strict=True)
        ]
        _wait(
            lambda: all(service.task(t.id).status.final for t in tasks),
            settings.task_timeout_s + 30.0,
        )
        done = [service.task(t.id) for t in tasks]
        rate = settings.control_rate_hz
        ends: list[float] = []
        ratios: list[float] = []
        for t in done:
            rid = t.robot_id
            seqs = final_seq.get(t.id)
            if rid is not None and seqs is not None and rid in start_seq:
                ends.append((seqs.get(rid, start_seq[rid]) - start_seq[rid]) / rate)
            if rid is not None and rid in ids:
                s = scenario.starts[ids.index(rid)]
                straight = math.hypot(t.request.goal.x - s[0], t.request.goal.y - s[1])
                if straight > 0:
                    ratios.append(recorder.driven.get(rid, 0.0) / straight)
        succeeded = sum(t.status == TaskStatus.SUCCEEDED for t in done)
        makespan = max(ends) if len(ends) == len(done) else horizon_s
        closest = recorder.closest
        collisions = sum(
            d < recorder.radius.get(a, 0.2) + recorder.radius.get(b, 0.2)
            for (a, b), d in closest.items()
        )
        if closest:
            min_sep = min(closest.values())
        elif scenario.obstacles:
            min_sep = _min_obstacle_distance(service, ids[0], scenario)
        else:
            min_sep = math.nan
        return FleetBenchRow(
            scenario=scenario.name,
            robots=len(ids),
            policy=policy,
            success_rate=succeeded / len(done),
            collisions=int(collisions),
            min_separation_m=round(min_sep, 3),
            makespan_s=round(makespan, 2),
            path_ratio=round(float(np.mean(ratios)) if ratios else math.nan, 3),
        )
    finally:
        terminate(proc, timeout=15)
        subscriber.undeclare()
        service.close()
        store.close()


def _min_obstacle_distance(service: FleetService, robot_id: str, scenario: FleetScenario) -> float:
    """Closest approach of a lone robot to a static obstacle's centre [m], from its path."""
    tasks = service.tasks(robot_id=robot_id)
    best = math.inf
    for task in tasks:
        for _, x, y, *_ in service.path(task.id):
            for o in scenario.obstacles:
                best = min(best, math.hypot(x - o.x, y - o.y))
    return best


def run_fleet_bench(
    scenarios: Sequence[FleetScenario],
    policies: Sequence[str] = POLICIES,
    time_scale: float = 5.0,
    horizon_s: float = 120.0,
    progress: Callable[[FleetBenchRow], None] | None = None,
) -> list[FleetBenchRow]:
    """Every scenario under every policy; one in-process router for the whole run."""
    for policy in policies:
        if policy not in POLICIES:
            raise ValueError(f"unknown policy {policy!r}; expected one of {POLICIES}")
    router_settings: Settings = load_settings(listen=["tcp/127.0.0.1:0"])
    rows: list[FleetBenchRow] = []
    with (
        tempfile.TemporaryDirectory(prefix="parkfleet-bench-") as tmp,
        open_session(router_settings, "router") as session,
    ):
        endpoint = tcp_endpoint(listening_locators(session))
        run_id = os.getpid()
        for k, scenario in enumerate(scenarios):
            for policy in policies:
                row = run_scenario(
                    session,
                    endpoint,
                    scenario,
                    policy,
                    fleet_name=f"bench{run_id}-{k}-{policy}",
                    workdir=Path(tmp),
                    time_scale=time_scale,
                    horizon_s=horizon_s,
                )
                rows.append(row)
                if progress is not None:
                    progress(row)
    return rows
