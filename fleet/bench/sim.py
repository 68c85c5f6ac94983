"""Throughput of the batch simulator against the plain per-robot Python loop.

Both paths run the same closed loop (Eq. (5) with the wraps (11)/(21), laws (17)/(20),
forward Euler on Eq. (3), no obstacles, no wheel limit) on the same random problems.
Throughput is counted in robot-steps per second: one robot advanced by one Euler step,
counted only while the robot is still active (the tolerances are tiny, so in practice no
robot finishes during the timed steps and every simulated robot-step counts).

Rates are per CPU second of this process (``time.process_time``), best of a few repeats:
numpy's elementwise ufuncs run on one core, and on a shared machine wall-clock time also
counts the time other processes hold the core. Wall-clock rates are reported alongside.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fleet.core.params import Tolerance
from fleet.core.reference import simulate_loop
from fleet.core.simulate import PAPER_DT, BatchProblem, simulate
from fleet.core.types import LAWS, GainTriple, Law, Posture

#: Robot counts of the issue's table.
ROBOT_COUNTS: tuple[int, ...] = (1, 100, 10_000, 100_000)

#: Tolerances so small that no robot reaches them during a timed run [m], [rad].
_NEVER = Tolerance(position=1e-9, heading=1e-9)


@dataclass(frozen=True)
class SimBenchRow:
    """Batch throughput for one fleet size and its ratio to the plain loop."""

    robots: int
    steps: int  # Euler steps of the timed run
    steps_per_s: float  # robot-steps per CPU second
    ratio_vs_loop: float  # steps_per_s / plain-loop robot-steps per CPU second
    wall_steps_per_s: float  # robot-steps per wall-clock second


@dataclass(frozen=True)
class BenchReport:
    """All rows plus the plain-loop measurement they are compared with."""

    rows: list[SimBenchRow]
    loop_robots: int
    loop_steps: int
    loop_steps_per_s: float  # per CPU second
    loop_wall_steps_per_s: float
    repeats: int  # each rate is the best of this many runs


@dataclass(frozen=True)
class RandomFleet:
    """A random fleet problem (fixed seed), as plain Python values and as arrays."""

    starts: list[Posture]
    goals: list[Posture]
    gains: list[GainTriple]
    laws: list[Law]

    def problem(self) -> BatchProblem:
        return BatchProblem.build(self.starts, self.goals, self.gains, self.laws, _NEVER)


def random_fleet(robots: int, seed: int = 0) -> RandomFleet:
    """Start and goal postures uniform in [-10, 10]^2 m x [-pi, pi) rad, gains in [0.5, 3],
    laws ccw/cw at random."""
    rng = np.random.default_rng(seed)

    def postures() -> list[Posture]:
        xy = rng.uniform(-10.0, 10.0, (robots, 2))
        theta = rng.uniform(-np.pi, np.pi, robots)
        return [(float(a), float(b), float(c)) for (a, b), c in zip(xy, theta, strict=True)]

    starts, goals = postures(), postures()
    k = rng.uniform(0.5, 3.0, (robots, 3))
    gains = [(float(a), float(b), float(c)) for a, b, c in k]
    laws = [LAWS[int(i)] for i in rng.integers(0, 2, robots)]
    return RandomFleet(starts, goals, gains, laws)


def _active_robot_steps(done: Sequence[bool], time_s: Sequence[float], steps: int) -> int:
    """Robot-steps actually applied: a robot done at step k counts k + 1 steps."""
    return sum(round(t / PAPER_DT) if d else steps for d, t in zip(done, time_s, strict=True))


@dataclass(frozen=True)
class Rate:
    """Best robot-steps per second over the repeats: per CPU second and per wall second."""

    cpu: float
    wall: float


def _best_rate(run: Callable[[], int], repeats: int) -> Rate:
    """Time ``run`` (which returns the robot-steps it did) ``repeats`` times."""
    cpu = wall = 0.0
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        work = run()
        c1, w1 = time.process_time(), time.perf_counter()
        # process_time ticks at ~1 us; guard a zero interval on tiny test runs
        cpu = max(cpu, work / max(c1 - c0, 1e-6))
        wall = max(wall, work / max(w1 - w0, 1e-9))
    return Rate(cpu, wall)


def batch_rate(robots: int, steps: int, repeats: int = 3, seed: int = 0) -> Rate:
    """Robot-steps per second of :func:`fleet.core.simulate.simulate`."""
    problem = random_fleet(robots, seed).problem()

    def run() -> int:
        result = simulate(problem, dt=PAPER_DT, max_time=steps * PAPER_DT)
        return _active_robot_steps(result.done.tolist(), result.time.tolist(), result.steps)

    return _best_rate(run, repeats)


def loop_rate(robots: int, steps: int, repeats: int = 3, seed: int = 0) -> Rate:
    """Robot-steps per second of the plain loop :func:`fleet.core.reference.simulate_loop`."""
    fleet = random_fleet(robots, seed)

    def run() -> int:
        runs = simulate_loop(
            fleet.starts,
            fleet.goals,
            fleet.gains,
            fleet.laws,
            tol_position=_NEVER.position,
            tol_heading=_NEVER.heading,
            dt=PAPER_DT,
            max_time=steps * PAPER_DT,
        )
        return sum(r.steps for r in runs)

    return _best_rate(run, repeats)


def steps_for(robots: int, robot_steps: int, min_steps: int, max_steps: int) -> int:
    """Steps for a timed run of about ``robot_steps`` robot-steps, clamped to the range."""
    return max(min_steps, min(max_steps, robot_steps // max(robots, 1)))


def run_sim_bench(
    robot_counts: Sequence[int] = ROBOT_COUNTS,
    robot_steps: int = 20_000_000,
    min_steps: int = 200,
    max_steps: int = 2_000,
    loop_robots: int = 50,
    loop_steps: int = 2_000,
    repeats: int = 3,
) -> BenchReport:
    """Measure the batch simulator for each fleet size and the plain loop once.

    ``max_steps`` (20 s of simulated time at dt = 0.01 s) keeps converging errors far from
    subnormal floats, which would slow both paths for reasons unrelated to the code.
    """
    loop = loop_rate(loop_robots, loop_steps, repeats)
    rows = []
    for robots in robot_counts:
        steps = steps_for(robots, robot_steps, min_steps, max_steps)
        rate = batch_rate(robots, steps, repeats)
        rows.append(SimBenchRow(robots, steps, rate.cpu, rate.cpu / loop.cpu, rate.wall))
    return BenchReport(rows, loop_robots, loop_steps, loop.cpu, loop.wall, repeats)


def quick_bench() -> BenchReport:
    """A tiny run for tests: same code paths, meaningless numbers."""
    return run_sim_bench(
        robot_counts=(1, 10),
        robot_steps=100,
        min_steps=5,
        max_steps=10,
        loop_robots=2,
        loop_steps=5,
        repeats=1,
    )
