"""Switching between laws (17) and (20) on the way: the rule the paper left as future work.

The paper ends: "Future work includes a switching rule between the two control laws to
obtain a more optimal path". This module is that rule for one robot (pure, vectorised over
independent trips).

**Rule (predictive, at checkpoints).** At the start, both fixed laws are rolled out to the
goal with the batch simulator (the same step the robots run); the robot takes the one with
the shorter predicted path (a law that does not arrive within the horizon counts as
infinitely long). At each of ``checkpoints`` instants spaced ``interval`` apart, both laws
are rolled out again from the robot's current pose; it switches when the other law's
predicted *remaining* path is shorter than its current law's by more than ``margin``.
After the last checkpoint it keeps its law to the goal.

**Path guarantee.** Let D_k be the distance driven up to checkpoint k plus the current
law's predicted remainder. The rollouts are exact for the model (deterministic, same step
and stop rule), so keeping the law leaves D_k unchanged and switching lowers it by more than
``margin``: the final path length is at most D_0 = the shorter of the two fixed laws, on
every trip, and shorter whenever any switch happened. (On a real robot the rollouts are
predictions; the guarantee then holds up to their error.)

**What stays of the stability argument.** Both laws command u = kx x_e, so
L = (x_e^2 + y_e^2) / 2 of Eq. (10.a) has dL/dt = -kx x_e^2 <= 0 under either law (10.d),
and under the wheel limit too (u and omega are scaled by the same positive factor): L is a
common Lyapunov-like function, the position error never grows, across switches included.
The heading parts of V (12.a) and P (22) are not common -- theta_e is re-wrapped from
[0, 2pi) to (-2pi, 0] or back at a switch, so V or P may jump -- which is why switching is
confined to finitely many checkpoints: after the last one a single law runs and the paper's
convergence argument for that law applies unchanged (x_e, y_e -> 0 by Barbalat, theta_e to
a neighbourhood of zero). The dwell time between switches is at least ``interval``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from fleet.core.params import UNLIMITED, Gains, RobotProfile, Tolerance
from fleet.core.simulate import PAPER_DT, BatchProblem, SimResult, simulate
from fleet.core.types import LAWS, BoolArray, FloatArray, Law

#: Checkpoints (possible switches) per trip by default.
CHECKPOINTS = 8
#: [m] a switch must shorten the predicted path by more than this (no chattering over
#: millimetres; the path guarantee holds for any margin >= 0).
MARGIN = 0.01


@dataclass(frozen=True)
class Segment:
    """From ``start_time`` [s] on, the robot drives with ``law``."""

    start_time: float
    law: Law


@dataclass(frozen=True)
class SwitchingRun:
    """Outcome per trip (arrays of shape (M,)) and the fixed laws' runs for comparison."""

    distance: FloatArray  # [m]
    control_effort: FloatArray  # Eq. (25)
    time: FloatArray  # [s]; NaN where not done
    done: BoolArray
    final_pose: FloatArray  # (M, 3)
    segments: list[list[Segment]]
    fixed: dict[Law, SimResult] = field(repr=False)
    interval: float = 0.0  # [s] between checkpoints

    @property
    def switches(self) -> npt.NDArray[np.int64]:
        return np.array([len(s) - 1 for s in self.segments], dtype=np.int64)

    def best_fixed_distance(self) -> FloatArray:
        """Per trip, the shorter path of the two fixed laws (inf where neither arrives)."""
        return np.minimum(*(_predicted(self.fixed[law]) for law in LAWS))


def _predicted(result: SimResult) -> FloatArray:
    return np.where(result.done, result.distance, math.inf)


def _rollout(
    pose: FloatArray,
    goal: FloatArray,
    gains: Mapping[Law, Gains],
    cw: npt.ArrayLike,
    tolerance: Tolerance,
    profile: RobotProfile,
    dt: float,
    max_time: float,
) -> SimResult:
    cw_arr = np.broadcast_to(np.asarray(cw, dtype=bool), (pose.shape[0],))
    rows = np.where(
        cw_arr[:, None], np.array(gains["cw"].as_tuple()), np.array(gains["ccw"].as_tuple())
    )
    problem = BatchProblem.build(pose, goal, rows, cw_arr, tolerance=tolerance, profile=profile)
    return simulate(problem, dt=dt, max_time=max_time)


def switching_run(
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    gains: Mapping[Law, Gains],
    tolerance: Tolerance,
    profile: RobotProfile = UNLIMITED,
    dt: float = PAPER_DT,
    max_time: float = 60.0,
    checkpoints: int = CHECKPOINTS,
    interval: float | None = None,
    margin: float = MARGIN,
) -> SwitchingRun:
    """Drive M independent trips (``start``, ``goal``: (M, 3) or (3,)) with the switching rule.

    ``gains`` maps each law to its gains; ``interval`` [s] between checkpoints defaults to
    the median predicted arrival time of the first choice over ``checkpoints + 1`` (one
    trip: its own arrival split evenly). ``max_time`` [s] bounds every run and rollout.
    """
    if checkpoints < 0 or not margin >= 0:
        raise ValueError("checkpoints must be >= 0 and margin >= 0")
    s = np.atleast_2d(np.asarray(start, dtype=np.float64))
    g = np.broadcast_to(np.atleast_2d(np.asarray(goal, dtype=np.float64)), s.shape).copy()
    m = s.shape[0]
    both = _rollout(
        np.vstack([s, s]),
        np.vstack([g, g]),
        gains,
        np.repeat([False, True], m),
        tolerance,
        profile,
        dt,
        max_time,
    )
    fixed = {law: _slice(both, i * m, (i + 1) * m) for i, law in enumerate(LAWS)}
    cw = _predicted(fixed["cw"]) < _predicted(fixed["ccw"])
    first_time = np.where(cw, fixed["cw"].time, fixed["ccw"].time)
    if interval is None:
        finite = first_time[np.isfinite(first_time)]
        horizon = float(np.median(finite)) if finite.size else max_time
        interval = horizon / (checkpoints + 1)
    steps = max(1, round(interval / dt))
    segments: list[list[Segment]] = [[Segment(0.0, "cw" if c else "ccw")] for c in cw]

    pose = s.copy()
    distance, effort = np.zeros(m), np.zeros(m)
    done = np.zeros(m, dtype=bool)
    time = np.full(m, np.nan)
    elapsed = 0
    for _ in range(checkpoints):
        left = max_time - elapsed * dt
        if left <= 0 or done.all():
            break
        active = np.flatnonzero(~done)
        leg = _rollout(
            pose[active],
            g[active],
            gains,
            cw[active],
            tolerance,
            profile,
            dt,
            min(steps * dt, left),
        )
        _advance(leg, active, pose, distance, effort, done, time, elapsed * dt)
        elapsed += min(steps, round(left / dt))
        active = np.flatnonzero(~done)
        if active.size == 0 or elapsed * dt >= max_time:
            break
        k = active.size
        ahead = _rollout(
            np.vstack([pose[active]] * 2),
            np.vstack([g[active]] * 2),
            gains,
            np.repeat([False, True], k),
            tolerance,
            profile,
            dt,
            max_time - elapsed * dt,
        )
        remaining = {
            law: _predicted(_slice(ahead, i * k, (i + 1) * k)) for i, law in enumerate(LAWS)
        }
        current = np.where(cw[active], remaining["cw"], remaining["ccw"])
        other = np.where(cw[active], remaining["ccw"], remaining["cw"])
        flip = other < current - margin
        for j in np.flatnonzero(flip):
            i = int(active[j])
            cw[i] = not cw[i]
            segments[i].append(Segment(elapsed * dt, "cw" if cw[i] else "ccw"))
    active = np.flatnonzero(~done)
    left = max_time - elapsed * dt
    if active.size and left > 0:
        leg = _rollout(pose[active], g[active], gains, cw[active], tolerance, profile, dt, left)
        _advance(leg, active, pose, distance, effort, done, time, elapsed * dt)
    # A trip that never switched drove one fixed law: report that run itself (summed in one
    # go, so equal to it bit for bit rather than up to the rounding of the legs' sums).
    for law in LAWS:
        kept = np.array([len(seg) == 1 and seg[0].law == law for seg in segments], dtype=bool)
        run = fixed[law]
        distance[kept], effort[kept] = run.distance[kept], run.control_effort[kept]
        done[kept], time[kept], pose[kept] = run.done[kept], run.time[kept], run.final_pose[kept]
    return SwitchingRun(
        distance=distance,
        control_effort=effort,
        time=time,
        done=done,
        final_pose=pose,
        segments=segments,
        fixed=fixed,
        interval=steps * dt,
    )


def _advance(
    leg: SimResult,
    rows: npt.NDArray[np.intp],
    pose: FloatArray,
    distance: FloatArray,
    effort: FloatArray,
    done: BoolArray,
    time: FloatArray,
    offset: float,
) -> None:
    """Add one leg's motion and metrics to the rows it simulated (in place)."""
    pose[rows] = leg.final_pose
    distance[rows] += leg.distance
    effort[rows] += leg.control_effort
    done[rows] = leg.done
    time[rows] = np.where(leg.done, offset + leg.time, np.nan)


def _slice(result: SimResult, lo: int, hi: int) -> SimResult:
    return SimResult(
        done=result.done[lo:hi],
        time=result.time[lo:hi],
        control_effort=result.control_effort[lo:hi],
        distance=result.distance[lo:hi],
        final_pose=result.final_pose[lo:hi],
        steps=result.steps,
    )
