"""Planner settings: search bounds, candidate delays, horizons, corridors (pure data)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from fleet.core.wire import DEFAULT_PASS_M


@dataclass(frozen=True)
class PlannerConfig:
    """Bounds and knobs of :func:`fleet.core.planner.plan` (times in robot seconds).

    Search (per cluster of interacting robots, :mod:`fleet.core.planner.search`):
    ``exhaustive_limit`` -- up to this many robots free to choose a law, every combination
    of laws is rolled out (2^k); ``budget`` -- rollouts per cluster for the local search
    after that; ``rounds`` -- its rounds repairing conflicts, ``improve_rounds`` -- its
    rounds shortening a safe plan (each round is one simulator call per segment);
    ``repair_targets`` -- robots of the earliest conflicts moved per round;
    ``improve_candidates`` -- candidates per improving round; ``delays_s`` --
    start delays
    tried for a robot in a conflict (added to its current one); ``change_penalty_s`` --
    a flip, new delay or hold of a robot under way must shorten the makespan by more than
    this to be chosen (keeps stable decisions stable); ``flip_gain_s`` -- a robot under
    way on its last leg within ``flip_within_m`` of its goal whose other law, alone from
    where it is, arrives more than this sooner is tried with it from the first round (the
    laws turn one way only: a robot that the disturbances or its peers turned past its
    goal's heading goes the long way round; farther out the law's rotation sense is the
    plan's way past its peers, and flips there jammed perfect robots in the car park);
    ``good_enough`` -- stop improving a
    safe plan once its makespan is within this factor of the solo lower bound.

    Horizon: ``horizon_factor`` x the slowest solo arrival (+ the largest delay), within
    [``min_horizon_s``, ``max_horizon_s``].

    Clusters (:mod:`fleet.core.planner.clusters`): robots interact when their predicted
    positions come within peer radius + ``interaction_margin_m`` of each other within
    ``cluster_slack_s`` of the same time; predictions are sampled every
    ``sample_period_s``; clusters whose chosen plans came to interact are searched again
    (``recheck_budget`` rollouts of conflict repair, ``merge_rounds`` times; then baseline
    and safety net only).

    Corridors: sampled every ``corridor_period_s``; the service re-plans when a robot is
    farther than ``corridor_radius_m`` from its corridor within ``corridor_slack_s``.

    Routes (:mod:`fleet.core.planner.roadmap`, when the site has static obstacles): a robot
    whose straight way to its goal is not clear gets via-points around the walls and posts,
    keeping its body ``contact_margin_m`` + ``route_slack_m`` clear of them, ending
    ``approach_m`` in front of its goal; it passes each within ``pass_m``.

    Open approaches (:func:`fleet.core.planner.scene.build_fleet`): a new robot without a
    route, behind its goal, is given one via-point on its goal's axis, the one of
    ``open_approach_m`` [m] in front of the goal with which it alone arrives first, when it
    then arrives more than ``open_approach_gain_s`` sooner than without: the laws reach the
    goal's heading with a lateral error they can only remove with a whole turn, and from
    near the axis they arrive without it. Empty: off.
    """

    exhaustive_limit: int = 4
    budget: int = 96
    rounds: int = 10
    improve_rounds: int = 1
    improve_candidates: int = 12
    delays_s: tuple[float, ...] = (1.5, 3.0, 6.0, 12.0)
    #: robots of an unsafe candidate's closest pairs that the local search moves per round
    repair_targets: int = 3
    change_penalty_s: float = 1.0
    flip_gain_s: float = 2.0
    flip_within_m: float = 2.0
    #: prioritised seed: delays it may give, and how far [m] beyond the separation placed
    #: paths must stay apart (half that from standing robots)
    reserve_delays_s: tuple[float, ...] = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 13.0, 16.0, 20.0)
    reserve_margin_m: float = 0.5
    good_enough: float = 1.1
    horizon_factor: float = 2.0
    min_horizon_s: float = 20.0
    max_horizon_s: float = 240.0
    interaction_margin_m: float = 0.5
    cluster_slack_s: float = 1.0
    sample_period_s: float = 0.5
    #: rollouts advance this long first (then twice as long each time); between segments
    #: unsafe or hopeless candidates stop [s]
    segment_s: float = 1.0
    merge_rounds: int = 2
    #: rollouts of a cluster searched again after the check (conflict repair only)
    recheck_budget: int = 24
    #: whole-fleet checks of the chosen plan (module docstring of plan.py, 6); each failed
    #: one holds the robots it would start into a conflict and checks again
    verify_rounds: int = 4
    #: [m] a standstill (every robot held) is planned again keeping contact distance + this
    standstill_margin_m: float = 0.02
    corridor_period_s: float = 0.5
    corridor_radius_m: float = 0.5
    corridor_slack_s: float = 2.0
    #: unnamed tasks: only this many nearest robots per task (and tasks per robot) are
    #: priced by rollout; the other pairs cost their straight-line lower bound x 2
    assignment_candidates: int = 8
    #: robots held: the service should try them again after this long
    hold_retry_s: float = 2.0
    #: solo predictions (clusters, horizons, assignment) use at least this step [s]
    solo_dt: float = 0.05
    max_rows_per_call: int = 1024
    approach_m: float = 1.0
    pass_m: float = DEFAULT_PASS_M
    route_slack_m: float = 0.15
    open_approach_m: tuple[float, ...] = (0.5, 1.0)
    open_approach_gain_s: float = 0.5

    def route_clearance(self, radius: float, contact_margin_m: float) -> float:
        """[m] how far a route keeps the centre of a robot of body ``radius`` [m] from every
        static body (rounded: the roadmap cache's key)."""
        return round(radius + contact_margin_m + self.route_slack_m, 6)

    def __post_init__(self) -> None:
        if self.exhaustive_limit < 0 or self.budget < 0 or self.rounds < 0:
            raise ValueError("search bounds must be >= 0")
        if any(d <= 0 for d in self.delays_s):
            raise ValueError("delays_s must be positive")
        if self.sample_period_s <= 0 or self.corridor_period_s <= 0:
            raise ValueError("sample periods must be positive")
        if self.approach_m < 0 or self.pass_m <= 0 or self.route_slack_m < 0:
            raise ValueError("approach_m and route_slack_m must be >= 0, pass_m > 0")
        if not (self.flip_gain_s >= 0 and self.flip_within_m >= 0):  # NaN too
            raise ValueError("flip_gain_s and flip_within_m must be >= 0 (inf: no flips)")
        if not all(0 < d < math.inf for d in self.open_approach_m):  # NaN too
            raise ValueError("open_approach_m must be positive and finite (empty: off)")
        if not self.open_approach_gain_s >= 0:
            raise ValueError("open_approach_gain_s must be >= 0")


__all__ = ["PlannerConfig"]
