"""Planner glue: what a plan depends on (the snapshot, copied under the lock), applying a
plan's decisions through the ledger (a stale plan is rebased, or dropped whole), the
proximity trigger and the planner's statistics. The planning itself is the pure
:func:`fleet.core.planner.plan`, run by :mod:`~fleet.service.planner_worker`.
"""

from __future__ import annotations

import logging
from collections import Counter

from fleet.core.planner import Plan
from fleet.core.wire import (
    RobotMode,
)
from fleet.service.horizon import close_pairs
from fleet.service.ledger import Outcome
from fleet.service.service_state import ServiceState
from fleet.service.snapshot import PlanInput, RobotFacts, planning_input, worth_planning
from fleet.service.stats import PlannerStats

_log = logging.getLogger(__name__)

_MOVING = frozenset({RobotMode.DRIVING, RobotMode.AVOIDING})


class PlannerGlue(ServiceState):
    """The fleet service's side of planning: snapshot, apply, proximity trigger, stats."""

    def _lead_time(self) -> float:
        """Expected delay [s, robot time] until a plan reaches the robots: the smoothed
        planning time, converted to robot time by the robots' observed control rate."""
        took = self._planner.plan_seconds
        if took is None:
            return 0.0
        scale = self._time_scale if self._time_scale is not None else 1.0
        return min(self.lead_time_max, took * scale)

    def _take_snapshot(self) -> PlanInput | None:
        """What a plan depends on, copied under the lock (references and small tuples);
        the snapshot objects are built after the lock is released."""
        now = self._clock.monotonic()
        with self._lock:
            if self._closed:
                return None
            robots = [
                RobotFacts(
                    rec.state,
                    rec.status,
                    now - rec.seen,
                    self._available(rec),
                    None if rec.description is None else rec.description.profile,
                )
                for rec in self._roster.records()
                if rec.state is not None and rec.status is not None and not rec.gone_for_good
            ]
            tasks = list(self._ledger.active.values())
            facts = self._ledger.facts(now)
            obstacles = list(self._obstacles)
            version = self._snapshot_version()
            lead_time = self._lead_time()
            scale = self._time_scale if self._time_scale is not None else 1.0
        if not worth_planning(robots, tasks):
            return None
        return planning_input(
            version, robots, tasks, obstacles, self.settings, lead_time, scale, facts
        )

    def _apply_plan(self, plan: Plan, work: PlanInput) -> None:
        """Apply a plan's decisions through the ledger; those on tasks that changed since
        the snapshot are dropped (a stale plan is rebased, or dropped whole)."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        outcomes: Counter[Outcome] = Counter()
        held = revised = 0
        relaxed = next((n for n in plan.notes if n.startswith("standstill")), None)
        with self._lock:
            if self._closed:
                return
            stale = plan.snapshot_version != self._snapshot_version()
            for d in plan.decisions:
                outcome, effects = self._ledger.apply(
                    d,
                    robot_available=self._available(self._roster.record(d.robot_id)),
                    plan_safe=plan.safe,
                    origin_seq=work.origin_seqs.get(d.robot_id),
                    now=now,
                    wall=wall,
                    relaxed=relaxed,
                )
                outcomes[outcome] += 1
                if outcome is Outcome.APPLIED:
                    self._queue(effects, now)
                    held += d.hold
                    revised += d.action == "revise"
        applied = outcomes[Outcome.APPLIED] + outcomes[Outcome.UNCHANGED]
        if stale and plan.decisions:
            self._counters.add("plans_rebased" if applied else "plans_stale_dropped")
        self._counters.add("decisions_stale_dropped", outcomes[Outcome.STALE])
        self._counters.add("plan_fallbacks", held)
        self._counters.add("replans", revised)
        if relaxed is not None:
            # No robot could move keeping the separation: planned at the standstill margin.
            self._counters.add("plans_relaxed")
            _log.warning("relaxed plan: %s", relaxed)
        if outcomes[Outcome.UNSAFE]:
            # A scene the plan could not keep apart (the robots' safety filter still keeps
            # their bodies apart): the decisions that would start robots in it are dropped.
            self._counters.add("plans_unsafe_dropped", outcomes[Outcome.UNSAFE])
            _log.warning(
                "dropped %d decision(s) that would start a robot in a plan predicted to come "
                "closer than the separation (min separation %.2f m); those robots stand",
                outcomes[Outcome.UNSAFE],
                plan.min_separation_m,
            )
        self._settle()

    def planner_stats(self) -> PlannerStats:
        """Planning latency p50/p99 [ms] over the last plans, fallbacks and drops."""
        window, count = self._planner.latency, self._counters.snapshot()
        p50, p99 = window.percentile(50), window.percentile(99)
        return PlannerStats(
            plans=count.get("plans", 0),
            window=len(window),
            p50_ms=None if p50 is None else 1e3 * p50,
            p99_ms=None if p99 is None else 1e3 * p99,
            fallbacks=count.get("plan_fallbacks", 0),
            rebased=count.get("plans_rebased", 0),
            stale_dropped=count.get("plans_stale_dropped", 0),
            decisions_stale_dropped=count.get("decisions_stale_dropped", 0),
            unsafe_dropped=count.get("plans_unsafe_dropped", 0),
            relaxed=count.get("plans_relaxed", 0),
        )

    def _positions(self) -> list[tuple[str, float, float, bool]]:
        """(id, x, y, moving) of every robot with a pose when some robot is moving (else
        none: the proximity trigger only watches robots under way)."""
        if not self._ledger.under_way:
            return []
        out = []
        for rec in self._roster.records():
            s = rec.state
            if s is not None:
                out.append((rec.robot_id, s.pose.x, s.pose.y, s.mode in _MOVING))
        return out

    def _check_separation(self, points: list[tuple[str, float, float, bool]]) -> None:
        """Re-plan when a pair of robots (one moving) comes closer than the separation plus
        the margin; once per pair while it stays that close."""
        near = self.settings.safety_separation_m + self.settings.replan_separation_margin_m
        pairs = close_pairs(points, near) if points else set()
        new = pairs - self._close_pairs
        self._close_pairs = pairs
        if new:
            self._counters.add("close_pairs_seen", len(new))
            self._planner.request("separation")
