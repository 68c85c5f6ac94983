"""Throughput of the batch simulator against a plain per-robot Python loop.

Two scenes, each run by :func:`fleet.core.simulate.simulate` (the compiled control step)
and by :func:`plain_loop`, a fair hand-written Python loop doing the same job (cos/sin once
per robot-step, everything inlined, the ``math`` module, no numpy):

* ``independent``: N = 1, 100, 10 000, 100 000 robots from random postures to random goals,
  laws (17)/(20) at random, no obstacles, no wheel limit, no interaction;
* ``peers``: 50 robots that all act on each other at every step (Eq. 27 with an influence
  radius larger than the yard), wheel-limited;
* ``peers+filter``: the same robots with the safety filter on as the fleet runs it (its
  ratio is against the same plain loop, which has no filter: the cost of the filter).

Throughput is counted in robot-steps per second: one robot advanced by one Euler step, while
it is still active (the tolerances are tiny, so no robot finishes during a timed run).
Rates are the best of a few repeats, per wall-clock second (the batch simulator spreads
large batches over both cores) and per CPU second of this process (``time.process_time``,
all threads: the work per core, less sensitive to other jobs on a shared machine). Ratios
are against the plain loop measured in the same run, wall clock to wall clock and CPU
second to CPU second.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from fleet.core.params import UNLIMITED, Avoidance, RobotProfile, SafetyConfig, Tolerance
from fleet.core.simulate import PAPER_DT, BatchProblem, SimResult, batch_filter, simulate
from fleet.core.step import SAFETY_OFF, Safety
from fleet.core.types import LAWS, GainTriple, Law, Posture

#: Robot counts of the independent scene.
ROBOT_COUNTS: tuple[int, ...] = (1, 100, 10_000, 100_000)
#: Robots of the peer scene; all of them interact at every step.
PEER_ROBOTS = 50
#: Peer influence radius of the peer scene [m]: larger than any distance robots starting in
#: the 20 m x 20 m yard reach at 1 m/s within the timed run (so every pair interacts).
PEER_RADIUS = 100.0

#: Tolerances so small that no robot reaches them during a timed run [m], [rad].
_NEVER = Tolerance(position=1e-9, heading=1e-9)
_WRAP = 2.0 * math.pi


@dataclass(frozen=True)
class SimBenchRow:
    """Throughput of one scene and fleet size, and its ratio to the plain loop."""

    scene: str  # "independent" or "peers"
    robots: int
    steps: int  # Euler steps of the timed run
    steps_per_s: float  # robot-steps per wall-clock second
    cpu_steps_per_s: float  # robot-steps per CPU second (all threads)
    ratio_vs_loop: float  # steps_per_s / the plain loop's, same scene, wall clock
    loop_steps_per_s: float  # the plain loop's robot-steps per wall-clock second
    cpu_ratio_vs_loop: float  # cpu_steps_per_s / the plain loop's per CPU second


@dataclass(frozen=True)
class BenchReport:
    """All rows; each rate is the best of ``repeats`` runs."""

    rows: list[SimBenchRow]
    repeats: int


@dataclass(frozen=True)
class RandomFleet:
    """A random fleet problem (fixed seed) as plain Python values, with the scene's
    interaction: ``avoidance`` None for independent robots."""

    starts: list[Posture]
    goals: list[Posture]
    gains: list[GainTriple]
    laws: list[Law]
    profile: RobotProfile = UNLIMITED
    avoidance: Avoidance | None = None
    safety: Safety = SAFETY_OFF

    def problem(self) -> BatchProblem:
        avoid = self.avoidance or Avoidance(k_avoid=0.0)
        return BatchProblem.build(
            self.starts,
            self.goals,
            self.gains,
            self.laws,
            _NEVER,
            self.profile,
            k_avoid=avoid.k_avoid,
            peer_radius=avoid.peer_radius if self.avoidance else 0.0,
            min_x_oa=avoid.min_x_oa,
            smoothing=avoid.smoothing_m,
            safety=self.safety,
        )


def random_fleet(robots: int, seed: int = 0, peers: bool = False) -> RandomFleet:
    """Start and goal postures uniform in [-10, 10]^2 m x [-pi, pi) rad, gains in [0.5, 3],
    laws ccw/cw at random; ``peers``: wheel-limited robots that all interact."""
    rng = np.random.default_rng(seed)

    def postures() -> list[Posture]:
        xy = rng.uniform(-10.0, 10.0, (robots, 2))
        theta = rng.uniform(-np.pi, np.pi, robots)
        return [(float(a), float(b), float(c)) for (a, b), c in zip(xy, theta, strict=True)]

    starts, goals = postures(), postures()
    k = rng.uniform(0.5, 3.0, (robots, 3))
    gains = [(float(a), float(b), float(c)) for a, b, c in k]
    laws = [LAWS[int(i)] for i in rng.integers(0, 2, robots)]
    if not peers:
        return RandomFleet(starts, goals, gains, laws)
    return RandomFleet(
        starts, goals, gains, laws, RobotProfile(),
        Avoidance(peer_radius=PEER_RADIUS, smoothing_m=0.0),  # the paper's term, as plain_loop
    )  # fmt: skip


@dataclass(frozen=True)
class LoopResult:
    """Final postures and Eq. (25) metrics of :func:`plain_loop`, per robot."""

    poses: list[Posture]
    effort: list[float]
    distance: list[float]


def plain_loop(fleet: RandomFleet, steps: int, dt: float = PAPER_DT) -> LoopResult:
    """``steps`` closed-loop steps of every robot in plain Python, all robots per step.

    The same maths as the compiled step -- error (5) with the wraps (11)/(21), laws (17)/(20),
    Eq. (27) among peers when ``fleet.avoidance`` is set (no safety filter), saturation
    when the profile is limited, Euler (3), effort (25) and distance -- written as one would
    by hand: cos/sin once per robot-step, no function calls in the loop. (The tolerances of
    the benchmark are never reached, so the stop rule is left out.)
    """
    cos, sin, exp = math.cos, math.sin, math.exp
    n = len(fleet.starts)
    x = [p[0] for p in fleet.starts]
    y = [p[1] for p in fleet.starts]
    th = [p[2] for p in fleet.starts]
    goal_heading = [g[2] % _WRAP for g in fleet.goals]
    cw = [law == "cw" for law in fleet.laws]
    profile = fleet.profile
    r, b, limit = profile.wheel_radius, profile.half_axle, profile.max_wheel_speed
    avoid = fleet.avoidance
    k_avoid = avoid.k_avoid if avoid else 0.0
    guard = avoid.min_x_oa if avoid else 0.0
    influence_sq = avoid.peer_radius**2 if avoid else 0.0
    effort, distance = [0.0] * n, [0.0] * n
    for _ in range(steps):
        nx, ny, nth = x[:], y[:], th[:]
        for i in range(n):
            xi, yi, ti = x[i], y[i], th[i]
            c, s = cos(ti), sin(ti)
            dx, dy = fleet.goals[i][0] - xi, fleet.goals[i][1] - yi
            x_e, y_e = c * dx + s * dy, c * dy - s * dx
            te = goal_heading[i] - ti % _WRAP
            if te < 0.0:
                te += _WRAP
            if cw[i] and te > 0.0:
                te -= _WRAP
            kx, ky, kt = fleet.gains[i]
            omega = (ky * (y_e * y_e) + kt * (te * te)) * exp(-abs(te))
            if cw[i]:
                omega = -omega
            repulsion = 0.0
            if k_avoid > 0.0:
                for j in range(n):
                    if j != i:
                        px, py = x[j] - xi, y[j] - yi
                        if px * px + py * py < influence_sq:
                            x_oa = c * px + s * py
                            x_oa_guarded = max(x_oa, guard) if x_oa >= 0.0 else min(x_oa, -guard)
                            repulsion -= k_avoid / x_oa_guarded
            u = kx * x_e + repulsion
            peak = max(abs((u + b * omega) / r), abs((u - b * omega) / r))
            if peak > limit:
                scale = limit / peak
                u, omega = u * scale, omega * scale
            nx[i], ny[i], nth[i] = xi + c * u * dt, yi + s * u * dt, ti + omega * dt
            effort[i] += (abs(omega) + abs(u)) * dt
            distance[i] += abs(u) * dt
        x, y, th = nx, ny, nth
    return LoopResult(list(zip(x, y, th, strict=True)), effort, distance)


def _active_robot_steps(result: SimResult) -> int:
    """Robot-steps actually applied: a robot done at step k counts k + 1 steps."""
    done, time_s = result.done.tolist(), result.time.tolist()
    return sum(
        round(t / PAPER_DT) if d else result.steps for d, t in zip(done, time_s, strict=True)
    )


@dataclass(frozen=True)
class Rate:
    """Best robot-steps per second over the repeats: per wall-clock and per CPU second."""

    wall: float
    cpu: float


def _best_rate(run: Callable[[], int], repeats: int) -> Rate:
    """Time ``run`` (which returns the robot-steps it did) ``repeats`` times."""
    wall = cpu = 0.0
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        work = run()
        c1, w1 = time.process_time(), time.perf_counter()
        # process_time ticks at ~1 us; guard a zero interval on tiny test runs
        wall = max(wall, work / max(w1 - w0, 1e-9))
        cpu = max(cpu, work / max(c1 - c0, 1e-6))
    return Rate(wall, cpu)


def batch_rate(fleet: RandomFleet, steps: int, repeats: int = 3) -> Rate:
    """Robot-steps per second of :func:`fleet.core.simulate.simulate`."""
    problem = fleet.problem()
    simulate(problem, dt=PAPER_DT, max_time=PAPER_DT)  # compiled (or loaded) before timing
    return _best_rate(
        lambda: _active_robot_steps(simulate(problem, dt=PAPER_DT, max_time=steps * PAPER_DT)),
        repeats,
    )


def loop_rate(fleet: RandomFleet, steps: int, repeats: int = 3) -> Rate:
    """Robot-steps per second of :func:`plain_loop`."""

    def run() -> int:
        plain_loop(fleet, steps)
        return len(fleet.starts) * steps

    return _best_rate(run, repeats)


def steps_for(robots: int, robot_steps: int, min_steps: int, max_steps: int) -> int:
    """Steps for a timed run of about ``robot_steps`` robot-steps, clamped to the range."""
    return max(min_steps, min(max_steps, robot_steps // max(robots, 1)))


def _row(scene: str, robots: int, steps: int, batch: Rate, loop: Rate) -> SimBenchRow:
    ratio, cpu_ratio = batch.wall / loop.wall, batch.cpu / loop.cpu
    return SimBenchRow(scene, robots, steps, batch.wall, batch.cpu, ratio, loop.wall, cpu_ratio)


def run_sim_bench(
    robot_counts: Sequence[int] = ROBOT_COUNTS,
    robot_steps: int = 20_000_000,
    min_steps: int = 200,
    max_steps: int = 2_000,
    loop_robots: int = 50,
    loop_steps: int = 2_000,
    peer_robots: int = PEER_ROBOTS,
    peer_steps: int = 2_000,
    peer_loop_steps: int = 100,
    repeats: int = 3,
) -> BenchReport:
    """Measure both scenes and their plain loops in one run.

    ``max_steps`` (20 s of simulated time at dt = 0.01 s) keeps converging errors far from
    subnormal floats, which would slow both paths for reasons unrelated to the code.
    """
    loop = loop_rate(random_fleet(loop_robots), loop_steps, repeats)
    rows = []
    for robots in robot_counts:
        steps = steps_for(robots, robot_steps, min_steps, max_steps)
        batch = batch_rate(random_fleet(robots), steps, repeats)
        rows.append(_row("independent", robots, steps, batch, loop))
    peers = random_fleet(peer_robots, peers=True)
    peer_loop = loop_rate(peers, peer_loop_steps, repeats)
    batch = batch_rate(peers, peer_steps, repeats)
    rows.append(_row("peers", peer_robots, peer_steps, batch, peer_loop))
    filtered = replace(peers, safety=batch_filter(SafetyConfig()))
    batch = batch_rate(filtered, peer_steps, repeats)
    rows.append(_row("peers+filter", peer_robots, peer_steps, batch, peer_loop))
    return BenchReport(rows, repeats)


def quick_bench() -> BenchReport:
    """A tiny run for tests: same code paths, meaningless numbers."""
    return run_sim_bench(
        robot_counts=(1, 10),
        robot_steps=100,
        min_steps=5,
        max_steps=10,
        loop_robots=2,
        loop_steps=5,
        peer_robots=4,
        peer_steps=5,
        peer_loop_steps=5,
        repeats=1,
    )
