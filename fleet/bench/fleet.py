"""``parkfleet bench fleet``: scenarios through the real fleet, and navground beside it.

Fleet policies (``auto``, ``cw``, ``ccw``, ``none``): each run starts, in this process, a
:class:`FleetService` opened as ``serve`` opens it (:func:`fleet.service.host.open_fleet`: a
fresh SQLite store, the Zenoh bus; one in-process router for the whole bench), and the
robots as one ``parkfleet sim`` subprocess: lockstep, time-scaled, with a real robot's
disturbances on by default (``--disturbed``: pose and actuation noise, 50-150 ms command
latency, peer states 20-200 ms late and 5 % lost) and ``--trace`` streaming every robot's
true pose and mode at every tick. Tasks are submitted through :meth:`FleetService.submit`
as an API client would, each at its ``arrival_s`` of simulated time (read from the robots'
state sequence numbers). The run ends when every task succeeded or at the scenario's
:attr:`~fleet.bench.scenarios.Scenario.end_s`; the bench, not the service, is the judge of
time (the service's own task timeout is pushed out of the way). ``auto`` lets the service
choose each law; ``cw`` / ``ccw`` fix it; ``none`` is ``ccw`` with K_avoid = 0, the safety
filter off and a separation of 1 µm to keep -- no repulsion, no filter, no start delays or
holds: the baseline without any avoidance.

Peer policies (``orca``, ``hrvo``, ``hl``, ``socialforce``): navground's behaviours in this
process (:mod:`fleet.bench.peers`) driving the same simulated robots as the fleet's
(``BenchOptions.robots``, ``sim_agent.robots.SimRobots`` from the CLI: the same drives,
disturbances, link and seed), with the same step, tolerances and time limit.

Every run is measured by the same code (:mod:`fleet.bench.metrics`) on time-aligned true
poses. Planning latency (fleet policies): the wall time of each of the service's plans,
from its cumulative counters ``plans`` and ``plan_us`` sampled while the run goes
(a sample covering k plans counts as k plans of the mean time).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import multiprocessing
import os
import subprocess
import tempfile
import threading
import time
import warnings
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from multiprocessing.pool import AsyncResult
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from fleet.bench.metrics import ARRIVAL_RADIUS_M, RunMetrics, RunResult, percentile
from fleet.bench.peers import (
    BEHAVIOURS,
    MODES,
    PeerRobots,
    PeerRun,
    assign_goals,
    goals_by_robot,
    run_peer,
)
from fleet.bench.plots import plot_run
from fleet.bench.scenarios import Scenario, random_yard, swap
from fleet.bench.solo_floor import law_alone, zone_floor
from fleet.core.params import Avoidance, SafetyConfig
from fleet.core.simulate import warm_parallel_kernel
from fleet.core.tasks import (
    Direction,
    FleetEvent,
    GoalRejected,
    RobotNotFound,
    Task,
    TaskEvent,
    TaskRequest,
    TaskStatus,
)
from fleet.core.types import FloatArray
from fleet.core.wire import Keys, Pose, RobotState
from fleet.io.decoder import Decoder
from fleet.io.processes import sim_command, terminate
from fleet.io.settings import Settings, load_settings
from fleet.io.trace import TraceChunk, read_header, read_trace
from fleet.io.transport import listening_locators, open_session, tcp_endpoint
from fleet.service.fleet_service import FleetService
from fleet.service.host import open_fleet
from fleet.service.planner_worker import plans_log

FLEET_POLICIES: tuple[str, ...] = ("auto", "cw", "ccw", "none")
PEER_POLICIES: tuple[str, ...] = tuple(BEHAVIOURS)
POLICIES: tuple[str, ...] = (*FLEET_POLICIES, *PEER_POLICIES)
#: ``parkfleet sim`` flags of the disturbed robots (sim_agent.disturbances.REALISTIC).
DISTURBED_FLAGS: tuple[str, ...] = ("--disturbed",)
#: The unmeasured fleet run before the first measured one: the planner's compiled code is
#: built (numba, first use in a fresh checkout: seconds of wall time, which at time scale
#: 5 were 15-23 s of a robot's wait for its first plan) or loaded from its cache. Before
#: it the bench builds the parallel kernel of large rollouts (about a minute, once per
#: install; built inside a plan it once held a 32-robot swap's robots for 40 s).
WARM_UP = swap(2, "left").model_copy(update={"name": "warm-up", "time_limit_s": 5.0})
#: Seeds of a scenario's disturbance sets lie this far apart (any yard seed is smaller).
DISTURBANCE_SEED_STRIDE = 1_000_003
#: The service's task timeout in the bench [s, wall]: out of the way, the bench judges time.
_SERVICE_TIMEOUT_S = 86_400.0
#: Wall seconds without simulated time moving before a run is declared broken.
STALL_S = 60.0
#: Wall seconds the robots get to come up.
STARTUP_S = 60.0
#: Where the bench's in-process router listens (any free loopback port).
LOOPBACK = "tcp/127.0.0.1:0"


class FleetBenchRow(BaseModel):
    """One scenario under one policy (units: metres, simulated seconds, milliseconds)."""

    scenario: str
    family: str
    seed: int | None
    robots: int
    policy: str
    success_rate: float
    collisions: int
    min_separation_m: float | None
    makespan_s: float
    path_ratio: float | None
    deadlocks: int
    plan_p50_ms: float | None
    plan_p99_ms: float | None
    obstacle_hits: int
    min_obstacle_clearance_m: float | None
    tasks: int
    arrived: int
    rejected: int
    time_limit_s: float
    wall_s: float
    stops_per_trip: float | None = None  # standstills inside trips, per task (metrics.py)
    cusps_per_trip: float | None = None  # reversals of the sign of u, per task
    plan_wait_s: float | None = None  # the last-arriving task's wait for the service [sim s]
    plan_wait_max_s: float | None = None  # the longest such wait of any task [sim s]
    planning_sim_s: float | None = None  # every plan's wall time x the time scale [sim s]
    time_scale: float | None = None  # simulated s per wall s of the run (fleet policies)
    disturbance_seed: int = 0  # which of the scenario's disturbance sets (scenario_seed)
    repeat: int = 0  # which run of the same scenario, seed and policy (``repeats``)
    #: the largest sum over robots of the time each, alone, spends in one single-robot zone
    #: [sim s]: the floor one-at-a-time zones put under the makespan (solo_floor.py)
    zone_solo_s: float | None = None
    #: the makespan if no robot met another: each task's arrival plus its robot's solo time
    #: under the faster law, perfect robots, the peers' assignment [sim s] (solo_floor.py)
    law_solo_s: float | None = None


@dataclass(frozen=True)
class BenchOptions:
    """How the bench runs: time scale of the sim robots, their disturbances (``parkfleet
    sim`` flags; empty: perfect robots), time-limit override [s, simulated], plot folder,
    folder keeping the sim traces, task stores and plans logs (else deleted), whether
    navground runs in a worker process beside the fleet runs,
    how many disturbance seeds each scenario runs with (every policy on each), how many
    times each (scenario, seed, policy) runs (the spread of one tree: a fleet run varies with
    the service's timing, the navground peers repeat exactly), whether a
    short unmeasured fleet run comes first (:data:`WARM_UP`), the
    robots' settings (profile, avoidance, control
    rate), and the robots the navground peers drive (the same as ``disturbances`` give
    the fleet's; built by the CLI, which may import the simulator)."""

    time_scale: float = 5.0
    disturbances: tuple[str, ...] = DISTURBED_FLAGS
    time_limit_s: float | None = None
    plots: Path | None = None
    traces: Path | None = None
    peer_worker: bool = True
    disturbance_seeds: int = 1
    repeats: int = 1
    warm_up: bool = True
    settings: Settings = field(default_factory=load_settings)
    robots: PeerRobots | None = None

    def limit(self, scenario: Scenario) -> Scenario:
        """``scenario`` with the overriding time limit, if any."""
        if self.time_limit_s is None:
            return scenario
        return scenario.model_copy(update={"time_limit_s": self.time_limit_s})


@dataclass
class Outcome:
    """A finished run: its metrics, task count, plan latencies [ms], rejections, wall [s];
    fleet runs: each task's wait for the service [sim s] (in the order of
    ``result.task_arrivals``, NaN: never left idle) and the time scale."""

    result: RunResult
    tasks: int
    plan_ms: list[float]
    rejected: int = 0
    wall_s: float = 0.0
    plan_waits: list[float] = field(default_factory=list)
    time_scale: float | None = None


def random_yard_scenario(n: int, seed: int, half: float | None = None) -> Scenario:
    """The old name of :func:`fleet.bench.scenarios.random_yard` (same points per seed)."""
    return random_yard(n, seed, half=half)


def scenario_seed(scenario: Scenario, disturbance_seed: int = 0) -> int:
    """A stable seed for the noise of a scenario's runs (its own seed, else from its name),
    the same for every policy; ``disturbance_seed`` k > 0 draws the k-th other set."""
    base = scenario.seed if scenario.seed is not None else zlib.crc32(scenario.name.encode())
    return base + DISTURBANCE_SEED_STRIDE * disturbance_seed


def _percentile(values: Sequence[float], q: float) -> float | None:
    return round(percentile(values, q), 1) if values else None


def _round(value: float | None, digits: int = 3) -> float | None:
    return None if value is None else round(value, digits)


def make_row(scenario: Scenario, policy: str, outcome: Outcome) -> FleetBenchRow:
    """The table row of a run (the same arithmetic for every policy)."""
    r = outcome.result
    arrived = r.success_count()
    stops, cusps = r.smoothness(outcome.tasks)
    waits = np.asarray(outcome.plan_waits, dtype=np.float64)
    last_wait = None
    if waits.size and waits.size == r.task_arrivals.size and arrived == waits.size:
        last_wait = float(waits[int(np.nanargmax(r.task_arrivals))])
    scale = outcome.time_scale
    return FleetBenchRow(
        scenario=scenario.name,
        family=scenario.group,
        seed=scenario.seed,
        robots=len(scenario.robots),
        policy=policy,
        success_rate=round(arrived / outcome.tasks, 4) if outcome.tasks else 1.0,
        collisions=r.collision_pairs,
        min_separation_m=_round(r.min_separation_m),
        makespan_s=round(r.makespan(outcome.tasks, scenario.end_s), 2),
        path_ratio=_round(r.path_ratio()),
        deadlocks=len(r.deadlocks),
        plan_p50_ms=_percentile(outcome.plan_ms, 50),
        plan_p99_ms=_percentile(outcome.plan_ms, 99),
        obstacle_hits=r.obstacle_hits,
        min_obstacle_clearance_m=_round(r.min_obstacle_clearance_m),
        tasks=outcome.tasks,
        arrived=arrived,
        rejected=outcome.rejected,
        time_limit_s=scenario.time_limit_s,
        wall_s=round(outcome.wall_s, 1),
        stops_per_trip=round(stops, 2),
        cusps_per_trip=round(cusps, 2),
        plan_wait_s=None if last_wait is None or math.isnan(last_wait) else round(last_wait, 2),
        plan_wait_max_s=(
            round(float(np.nanmax(waits)), 2) if waits.size and not np.isnan(waits).all() else None
        ),
        planning_sim_s=None if scale is None else round(sum(outcome.plan_ms) / 1e3 * scale, 2),
        time_scale=scale,
    )


def metrics_title(row: FleetBenchRow) -> str:
    """The summary of a run used as a plot title (three short lines)."""
    sep = "-" if row.min_separation_m is None else f"{row.min_separation_m:.2f} m"
    ratio = "-" if row.path_ratio is None else f"{row.path_ratio:.2f}"
    plan = (
        ""
        if row.plan_p50_ms is None
        else f" | plan p50/p99 {row.plan_p50_ms:g}/{row.plan_p99_ms:g} ms"
    )
    return (
        f"{row.scenario} | {row.policy}\n"
        f"success {row.success_rate:.0%} | collisions {row.collisions} | min sep {sep} | "
        f"makespan {row.makespan_s:.1f} s\n"
        f"path ratio {ratio} | deadlocks {row.deadlocks} | obstacle hits {row.obstacle_hits}{plan}"
    )


def arrival_radius(scenario: Scenario) -> float:
    """How close to its goal [m] a robot reporting ``arrived`` completes its task: the
    scenario's position tolerance plus slack for the pose noise, at least the default."""
    return max(ARRIVAL_RADIUS_M, scenario.tolerance.position + 0.15)


# -- navground peers -----------------------------------------------------------------------


def run_peer_policy(
    scenario: Scenario, policy: str, options: BenchOptions, seed: int | None = None
) -> Outcome:
    """One navground run of ``scenario`` (robots seeded by ``seed``, default
    :func:`scenario_seed`), measured on its ticks."""
    began = time.monotonic()
    s = options.settings
    owner = assign_goals(scenario)
    metrics = RunMetrics(
        [s.profile.radius] * len(scenario.robots),
        goals_by_robot(scenario, owner),
        scenario.static_obstacles(),
        MODES,
        t_end=scenario.end_s,
        arrival_radius_m=arrival_radius(scenario),
    )
    run = PeerRun(
        behaviour=policy,
        profile=s.profile,
        safety_separation_m=s.safety_separation_m,
        contact_margin_m=s.safety.contact_margin_m,
        dt=1.0 / s.control_rate_hz,
        seed=scenario_seed(scenario) if seed is None else seed,
        robots=options.robots,
    )
    for chunk in run_peer(scenario, run):
        metrics.add(chunk)
    return Outcome(metrics.result(), len(scenario.robots), [], wall_s=time.monotonic() - began)


# -- the fleet over Zenoh ------------------------------------------------------------------


class _SimClock:
    """Simulated time of the sim robots [s]: one robot's state sequence number x period."""

    def __init__(self, period: float) -> None:
        self.period = period
        self._decoder = Decoder("bench clock")
        self._lock = threading.Lock()
        self._seq: int | None = None
        self._heard = time.monotonic()

    def on_sample(self, sample: Any) -> None:
        state = self._decoder.decode(RobotState, sample.payload.to_bytes())
        if state is not None:
            with self._lock:
                if self._seq is None or state.seq > self._seq:
                    self._seq = state.seq
                    self._heard = time.monotonic()

    def now(self) -> float | None:
        with self._lock:
            return None if self._seq is None else self._seq * self.period

    def stalled_for(self) -> float:
        """Wall seconds since simulated time last moved."""
        with self._lock:
            return time.monotonic() - self._heard


class _PlanLatency:
    """Per-plan wall times [ms] from the service's cumulative ``plans``/``plan_us``."""

    def __init__(self) -> None:
        self.samples: list[float] = []
        self._plans = 0
        self._wall_ms = 0.0

    def sample(self, counters: dict[str, int]) -> None:
        plans, wall = counters.get("plans", 0), counters.get("plan_us", 0) / 1000.0
        if plans > self._plans:
            k = plans - self._plans
            self.samples.extend([(wall - self._wall_ms) / k] * k)
        self._plans, self._wall_ms = plans, wall


@contextlib.contextmanager
def _plans_kept_in(path: Path) -> Iterator[None]:
    """The service's plans log (one JSON line per plan,
    :mod:`fleet.service.planner_worker`) written to ``path`` while the run lasts, and
    nowhere else."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(path, encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(message)s"))
    level, propagate = plans_log.level, plans_log.propagate
    plans_log.addHandler(handler)
    plans_log.setLevel(logging.DEBUG)
    plans_log.propagate = False
    try:
        yield
    finally:
        plans_log.removeHandler(handler)
        handler.close()
        plans_log.setLevel(level)
        plans_log.propagate = propagate


def _direction(policy: str) -> Direction:
    return "cw" if policy == "cw" else "auto" if policy == "auto" else "ccw"


def run_fleet_policy(
    session: Any,
    endpoint: str,
    scenario: Scenario,
    policy: str,
    options: BenchOptions,
    *,
    fleet_name: str,
    workdir: Path,
    seed: int | None = None,
    repeat: int = 0,
) -> Outcome:
    """One run of ``scenario`` through a fresh service and fresh ``parkfleet sim`` robots
    (``repeat`` > 0: another run of the same seed, its trace named so)."""
    began = time.monotonic()
    base = options.settings
    update: dict[str, Any] = {
        "fleet_name": fleet_name,
        "task_timeout_s": _SERVICE_TIMEOUT_S,
        "data_dir": (options.traces or workdir) / fleet_name,  # a fresh task store per run
        "yard": scenario.bounds,
    }
    if policy == "none":  # no repulsion, no filter, 1 µm to keep: the planner holds no one
        update |= {
            "avoidance": Avoidance(k_avoid=0.0),
            "safety_separation_m": 1e-6,
            "safety": SafetyConfig(enabled=False),
        }
    settings = base.model_copy(update=update)
    site = scenario.site()
    if site is not None:  # its single-robot zones
        settings = settings.with_site(site)
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
    other = seed is not None and seed != scenario_seed(scenario)  # another disturbance set
    trace = (options.traces or workdir) / (
        f"{scenario.name}--{policy}{f'--seed{seed}' if other else ''}"
        f"{f'--r{repeat}' if repeat else ''}.trace"
    )
    keys = Keys(fleet_name)
    clock = _SimClock(1.0 / settings.control_rate_hz)
    latency = _PlanLatency()
    succeeded: set[str] = set()

    def on_event(event: FleetEvent) -> None:
        if isinstance(event, TaskEvent) and event.task.status == TaskStatus.SUCCEEDED:
            succeeded.add(event.task.id)

    env = dict(os.environ)
    env["PARKFLEET_FLEET_NAME"] = fleet_name
    env["PARKFLEET_AVOIDANCE__K_AVOID"] = str(settings.avoidance.k_avoid)
    env["PARKFLEET_SAFETY__ENABLED"] = "true" if settings.safety.enabled else "false"
    env["PARKFLEET_CONTROL_RATE_HZ"] = str(settings.control_rate_hz)
    command = sim_command(
        endpoint,
        len(ids),
        time_scale=options.time_scale,
        spawn=str(spawn),
        seed=scenario_seed(scenario) if seed is None else seed,
        extra=[*options.disturbances, "--trace", str(trace)],
    )
    tasks: dict[int, Task] = {}
    submitted: dict[int, float] = {}  # simulated time [s] of each task's submission
    rejected = 0
    with contextlib.ExitStack() as stack:  # closed in reverse: sim, subscriber, the fleet
        if options.traces is not None:
            stack.enter_context(_plans_kept_in(options.traces / fleet_name / "plans.jsonl"))
        service = stack.enter_context(open_fleet(settings, session=session)).service
        service.add_listener(on_event)
        stack.callback(session.declare_subscriber(keys.state(ids[0]), clock.on_sample).undeclare)
        proc = subprocess.Popen(
            command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        stack.callback(terminate, proc, 15)
        service.set_obstacles(scenario.static_obstacles())
        deadline = time.monotonic() + STARTUP_S
        while len(service.robots()) < len(ids) or clock.now() is None:
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError(f"{scenario.name}: the simulated robots did not come up")
            time.sleep(0.05)
        t0 = clock.now()
        assert t0 is not None
        pending = sorted(range(len(ids)), key=lambda k: scenario.robots[k].arrival_s)
        while True:
            now = clock.now()
            assert now is not None
            while pending and scenario.robots[pending[0]].arrival_s <= now - t0:
                k = pending.pop(0)
                task = _submit(service, scenario, k, ids[k], _direction(policy))
                if task is None:
                    rejected += 1
                else:
                    tasks[k] = task
                    submitted[k] = now
            latency.sample(service.counters)
            if not pending and all(t.id in succeeded for t in tasks.values()):
                break
            if now - t0 >= scenario.end_s:
                break
            if proc.poll() is not None or clock.stalled_for() > STALL_S:
                raise RuntimeError(
                    f"{scenario.name}: the simulated robots stopped (exit {proc.poll()})"
                )
            time.sleep(0.02)
        latency.sample(service.counters)
        owners = {k: service.task(t.id).robot_id for k, t in tasks.items()}
    goals = np.full((len(ids), 3), np.nan)  # a robot's last task (its path, deadlocks)
    served: list[tuple[int, float, float]] = []  # every task: (robot, goal x, goal y)
    waits = PlanWait()
    for k, robot in owners.items():
        if robot in ids:
            goal = scenario.robots[k].goal
            goals[ids.index(robot)] = goal
            served.append((ids.index(robot), goal[0], goal[1]))
            waits.expect(ids.index(robot), submitted[k])
    result = _measure_trace(trace, goals, served, scenario, t0, waits)
    if options.traces is None:
        trace.unlink(missing_ok=True)
    return Outcome(
        result,
        len(ids),
        latency.samples,
        rejected,
        time.monotonic() - began,
        plan_waits=waits.waits.tolist(),
        time_scale=options.time_scale,
    )


def _submit(
    service: FleetService, scenario: Scenario, k: int, robot_id: str, direction: Direction
) -> Task | None:
    goal = scenario.robots[k].goal
    try:
        return service.submit(
            TaskRequest(
                goal=Pose(x=goal[0], y=goal[1], theta=goal[2]),
                robot_id=robot_id if scenario.named else None,
                direction=direction,
                law_gains=scenario.law_gains,
                tolerance=scenario.tolerance,
            )
        )
    except (GoalRejected, RobotNotFound):
        return None


class PlanWait:
    """Each task's wait for the service [simulated s]: from its submission to the first
    tick its robot is neither idle nor arrived (assigned: waiting on a planned start delay,
    driving, ...). At time scale S every wall second the service takes -- planning above
    all -- is S simulated seconds of this wait."""

    def __init__(self) -> None:
        self._robot: list[int] = []
        self._since: list[float] = []
        self.waits = np.zeros(0)

    def expect(self, robot: int, submitted_s: float) -> None:
        self._robot.append(robot)
        self._since.append(submitted_s)
        self.waits = np.full(len(self._robot), np.nan)

    def add(self, chunk: TraceChunk, modes: Sequence[str]) -> None:
        passive = [k for k, m in enumerate(modes) if m in ("idle", "arrived")]
        for task in np.nonzero(np.isnan(self.waits))[0]:
            robot, since = self._robot[task], self._since[task]
            going = (chunk.t >= since - 1e-9) & ~np.isin(chunk.modes[:, robot], passive)
            if going.any():
                self.waits[task] = float(chunk.t[int(np.argmax(going))]) - since


def _measure_trace(
    path: Path,
    goals: FloatArray,
    tasks: Sequence[tuple[int, float, float]],
    scenario: Scenario,
    t0: float,
    waits: PlanWait | None = None,
) -> RunResult:
    header = read_header(path)
    metrics = RunMetrics(
        header.radii,
        goals,
        scenario.static_obstacles(),
        header.modes,
        t_start=t0,
        t_end=t0 + scenario.end_s,
        tasks=tasks,
        arrival_radius_m=arrival_radius(scenario),
    )
    for chunk in read_trace(path):
        metrics.add(chunk)
        if waits is not None:
            waits.add(chunk, header.modes)
    return metrics.result()


# -- the whole bench -----------------------------------------------------------------------


def run_fleet_bench(
    scenarios: Sequence[Scenario],
    policies: Sequence[str] = POLICIES,
    options: BenchOptions | None = None,
    progress: Callable[[int, int, FleetBenchRow], None] | None = None,
    starting: Callable[[Scenario, str], None] | None = None,
) -> list[FleetBenchRow]:
    """Every scenario under every policy, rows in (scenario, policy) order.

    ``starting(scenario, policy)`` before each fleet run, ``progress(done, total, row)``
    after each run. With both kinds of policies and ``options.peer_worker``, the navground
    runs go to one spawned worker process meanwhile (a fleet run mostly waits on its
    time-scaled robots), and are reported as they finish.
    """
    options = options or BenchOptions()
    unknown = [p for p in policies if p not in POLICIES]
    if unknown:
        raise ValueError(f"unknown policy {unknown}; expected some of {list(POLICIES)}")
    cases = [
        (s, d, r)
        for s in scenarios
        for d in range(options.disturbance_seeds)
        for r in range(options.repeats)
    ]
    runs = [(k, options.limit(s), p) for k, (s, _, _) in enumerate(cases) for p in policies]

    def seed(k: int) -> int:
        return scenario_seed(cases[k][0], cases[k][1])

    fleet_runs = [r for r in runs if r[2] in FLEET_POLICIES]
    peer_runs = [r for r in runs if r[2] not in FLEET_POLICIES]
    done: dict[tuple[int, str], FleetBenchRow] = {}

    floors = {s.name: zone_floor(s, options.settings) for s in scenarios}
    alone = {s.name: law_alone(s, options.settings) for s in scenarios}

    def finish(k: int, scenario: Scenario, policy: str, outcome: Outcome) -> None:
        _, disturbance, repeat = cases[k]
        row = make_row(scenario, policy, outcome).model_copy(
            update={
                "disturbance_seed": disturbance,
                "repeat": repeat,
                "zone_solo_s": floors[scenario.name],
                "law_solo_s": alone[scenario.name],
            }
        )
        if options.plots is not None:
            tail = (f"--d{disturbance}" if disturbance else "") + (f"--r{repeat}" if repeat else "")
            name = f"{scenario.name}--{policy}{tail}.png"
            plot_run(scenario, outcome.result, metrics_title(row), options.plots / name)
        done[k, policy] = row
        if progress is not None:
            progress(len(done), len(runs), row)

    if options.traces is not None:
        options.traces.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as stack:
        pending: list[tuple[int, Scenario, str, AsyncResult[Outcome]]] = []
        if options.peer_worker and fleet_runs and peer_runs:
            pool = multiprocessing.get_context("spawn").Pool(1)  # never fork: sessions open
            stack.callback(pool.join)
            stack.callback(pool.terminate)
            pending = [
                (k, s, p, pool.apply_async(run_peer_policy, (s, p, options, seed(k))))
                for k, s, p in peer_runs
            ]
        else:
            fleet_runs = runs

        def collect(wait: bool) -> None:
            while pending and (wait or pending[0][3].ready()):
                k, scenario, policy, result = pending.pop(0)
                finish(k, scenario, policy, result.get())

        tmp = stack.enter_context(tempfile.TemporaryDirectory(prefix="parkfleet-bench-"))
        session: Any = None
        endpoint = ""
        if any(p in FLEET_POLICIES for _, _, p in fleet_runs):
            session = stack.enter_context(open_session(load_settings(listen=[LOOPBACK]), "router"))
            endpoint = tcp_endpoint(listening_locators(session))
        if options.warm_up and any(p in FLEET_POLICIES for _, _, p in fleet_runs):
            # The planner's kernel for large rollouts, into numba's cache: otherwise each
            # planner process of a fresh install plans on one thread while it compiles.
            kernel = warm_parallel_kernel()
            if kernel != "ready":
                warnings.warn(f"large rollouts run on one thread: {kernel}", stacklevel=1)
            run_fleet_policy(
                session,
                endpoint,
                WARM_UP,
                "auto",
                options,
                fleet_name=f"bench{os.getpid()}-warm-up",
                workdir=Path(tmp),
            )
        for k, scenario, policy in fleet_runs:
            if starting is not None:
                starting(scenario, policy)
            if policy in FLEET_POLICIES:
                name = f"bench{os.getpid()}-{k}-{policy}"
                outcome = run_fleet_policy(
                    session,
                    endpoint,
                    scenario,
                    policy,
                    options,
                    fleet_name=name,
                    workdir=Path(tmp),
                    seed=seed(k),
                    repeat=cases[k][2],
                )
            else:
                outcome = run_peer_policy(scenario, policy, options, seed(k))
            finish(k, scenario, policy, outcome)
            collect(wait=False)
        collect(wait=True)
    return [done[k, p] for k, _, p in runs]


class SummaryRow(BaseModel):
    """A family under one policy over its seeds: mean and worst of each figure."""

    family: str
    robots: int
    policy: str
    runs: int
    success_mean: float
    success_worst: float
    collisions_mean: float
    collisions_worst: int
    min_separation_worst_m: float | None
    makespan_mean_s: float
    makespan_worst_s: float
    path_ratio_mean: float | None
    path_ratio_worst: float | None
    deadlocks_mean: float
    deadlocks_worst: int
    obstacle_hits_worst: int = 0  # robots that hit a static obstacle, worst run
    plan_p99_worst_ms: float | None
    stops_mean: float | None = None  # per trip
    cusps_mean: float | None = None  # per trip
    plan_wait_mean_s: float | None = None  # the last-arriving task's wait [sim s]
    planning_sim_mean_s: float | None = None  # plans' wall time x time scale [sim s]


def summarise(rows: Iterable[FleetBenchRow]) -> list[SummaryRow]:
    """Rows grouped by (family, policy), in first-seen order."""
    groups: dict[tuple[str, str], list[FleetBenchRow]] = {}
    for row in rows:
        groups.setdefault((row.family, row.policy), []).append(row)
    out = []
    for (family, policy), group in groups.items():
        seps = [r.min_separation_m for r in group if r.min_separation_m is not None]
        ratios = [r.path_ratio for r in group if r.path_ratio is not None]
        plans = [r.plan_p99_ms for r in group if r.plan_p99_ms is not None]

        def mean(values: list[float | None]) -> float | None:
            known = [v for v in values if v is not None]
            return round(float(np.mean(known)), 2) if known else None

        out.append(
            SummaryRow(
                family=family,
                robots=group[0].robots,
                policy=policy,
                runs=len(group),
                success_mean=round(float(np.mean([r.success_rate for r in group])), 4),
                success_worst=min(r.success_rate for r in group),
                collisions_mean=round(float(np.mean([r.collisions for r in group])), 2),
                collisions_worst=max(r.collisions for r in group),
                min_separation_worst_m=min(seps) if seps else None,
                makespan_mean_s=round(float(np.mean([r.makespan_s for r in group])), 2),
                makespan_worst_s=max(r.makespan_s for r in group),
                path_ratio_mean=round(float(np.mean(ratios)), 3) if ratios else None,
                path_ratio_worst=max(ratios) if ratios else None,
                deadlocks_mean=round(float(np.mean([r.deadlocks for r in group])), 2),
                deadlocks_worst=max(r.deadlocks for r in group),
                obstacle_hits_worst=max(r.obstacle_hits for r in group),
                plan_p99_worst_ms=max(plans) if plans else None,
                stops_mean=mean([r.stops_per_trip for r in group]),
                cusps_mean=mean([r.cusps_per_trip for r in group]),
                plan_wait_mean_s=mean([r.plan_wait_s for r in group]),
                planning_sim_mean_s=mean([r.planning_sim_s for r in group]),
            )
        )
    return out
