"""Submission and bays: validate a goal, reserve it while the task is written, add it to
the ledger once stored (group commit: the store is written outside the lock); named bays
and bay groups of the site map; cancelling.
"""

from __future__ import annotations

import logging
import threading
import uuid
from collections.abc import Callable

from fleet.core.goals import Occupied, validate_goal
from fleet.core.planner.config import PlannerConfig
from fleet.core.route import lane_shapes
from fleet.core.tasks import (
    BayTaken,
    GoalRejected,
    RobotNotFound,
    Task,
    TaskConflict,
    TaskNotFound,
    TaskRequest,
)
from fleet.core.wire import (
    Pose,
)
from fleet.service.bays import BayState
from fleet.service.service_state import ServiceState

_log = logging.getLogger(__name__)


class Submission(ServiceState):
    """Task submission (plain goals and bays) and cancelling of one fleet service."""

    def _occupied(self, goal: Pose, exclude_robot: str | None) -> list[Occupied]:
        """Active (and pending) goals within the peer radius of ``goal``, and parked robots
        (arrived, holding or lost) near it that no active task names or holds."""
        radius = self.settings.avoidance.peer_radius
        out = list(self._ledger.goals.near(goal.x, goal.y, radius))
        claims = self._ledger.claims
        for parked in self._roster.parked_near(goal.x, goal.y, radius):
            if parked.robot_id != exclude_robot and parked.robot_id not in claims:
                out.append(parked)
        return out

    def submit(self, request: TaskRequest, idempotency_key: str | None = None) -> Task:
        """Validate, store (``queued``) and schedule a parking task; returns the stored task.

        Raises :class:`GoalRejected` (with the reason) or :class:`RobotNotFound`. A repeated
        ``idempotency_key`` returns the task first created with it, whatever the body.
        """
        while True:
            if idempotency_key is not None:
                existing = self._store.find_by_idempotency_key(idempotency_key)
                if existing is not None:
                    return existing
            with self._lock:
                # A request with the same key is being stored: wait for it (its task is
                # the answer), instead of rejecting this one as too near its goal.
                writing = self._keys_in_flight.get(idempotency_key or "")
            if writing is None:
                break
            writing.wait(10.0)
        wall = self._clock.wall()
        task = Task(id=uuid.uuid4().hex, request=request, created_at=wall, updated_at=wall)
        if not self._reserve(task, idempotency_key):
            return self.submit(request, idempotency_key)  # lost a race: wait as above
        try:
            self._check_route(request.goal, request.robot_id)  # after the cheaper checks
            stored = self._store.save_new(task, idempotency_key)
        except BaseException:
            with self._lock:
                self._ledger.release(task.id)
            raise
        finally:
            if idempotency_key is not None:
                with self._lock:
                    self._keys_in_flight.pop(idempotency_key).set()
        with self._lock:
            if stored.id != task.id:  # a concurrent request with the same key won
                self._ledger.release(task.id)
                return stored
            # stored: now the planner may see it
            self._queue(self._ledger.add(stored), self._clock.monotonic())
        self._settle()
        self._planner.request("task_submitted", burst=True)
        return stored

    def _check_route(self, goal: Pose, robot_id: str | None) -> None:
        """Refuse (:class:`GoalRejected`) a goal that the site's walls and posts leave no
        route to (:mod:`fleet.core.planner.roadmap`): from the robot named, or from every
        robot in service whose pose is known. No check without static obstacles or robots.
        Runs outside the lock (a route query is milliseconds of geometry)."""
        with self._lock:
            obstacles = tuple(self._obstacles)
            starts = [
                (rec.robot_id, rec.state.pose, self._profile_of(rec.robot_id).radius)
                for rec in self._roster.records()
                if rec.state is not None
                and rec.in_service
                and (robot_id is None or rec.robot_id == robot_id)
            ]
        if not obstacles or not starts:
            return
        from fleet.core.planner.lanes import route_graph  # the server's packages: first use

        config = PlannerConfig()
        margin = self.settings.safety.contact_margin_m
        site = self.settings.site
        lanes = () if site is None else lane_shapes(site.lanes)
        for _, pose, radius in starts:
            roadmap = route_graph(obstacles, config.route_clearance(radius, margin), lanes)
            if roadmap.route((pose.x, pose.y), goal.as_tuple(), config.approach_m) is not None:
                return
        whom = f"robot {starts[0][0]}" if robot_id is not None else f"any of {len(starts)} robots"
        raise GoalRejected(
            f"no route to goal ({goal.x:.2f}, {goal.y:.2f}) from {whom}: the site's walls and "
            "posts leave no way there wide enough for the robot"
        )

    def _reserve(self, task: Task, idempotency_key: str | None) -> bool:
        """Validate ``task``'s goal and reserve it (and its key) for the write; False if a
        request with the same key is being written meanwhile."""
        request, goal = task.request, task.request.goal
        with self._lock:
            if idempotency_key is not None and idempotency_key in self._keys_in_flight:
                return False
            rid = request.robot_id
            named = None if rid is None else self._roster.record(rid)
            if rid is not None and named is None:
                raise RobotNotFound(f"robot {rid} not found")
            if named is not None and not named.in_service:
                raise TaskConflict(f"robot {rid} is decommissioned: commission it first")
            if (
                named is not None
                and named.description is not None
                and not named.description.may_reverse
            ):
                raise TaskConflict(
                    f"robot {rid} says it may not reverse (may_reverse false), and laws "
                    "(17)/(20) reverse near the goal: the fleet does not park it"
                )
            self._ledger.bays.check(task)
            site = self.settings.site
            validate_goal(
                goal,
                self.settings.yard,
                self._obstacles,
                self._occupied(goal, rid),
                self.settings.avoidance.peer_radius,
                () if site is None else site.keep_out,
                margin=self._profile_of(rid).radius,
                contact_margin=self.settings.safety.contact_margin_m,
                zones=self._ledger.zones.shapes,
            )
            # Reserve the goal and bay while the task is written (outside the lock, so
            # concurrent submits share one commit): a concurrent submit near it (or for the
            # same bay) is rejected meanwhile.
            self._ledger.reserve(task)
            if idempotency_key is not None:
                self._keys_in_flight[idempotency_key] = threading.Event()
        return True

    def submit_to_bay(
        self,
        bay: str | None,
        group: str | None,
        make: Callable[[Pose, str], TaskRequest],
        idempotency_key: str | None = None,
    ) -> Task:
        """Submit a task whose goal is a named bay, or any free bay of ``group``
        (``make(pose, bay)`` builds the request). The bay is reserved by the task while it
        is active. Raises :class:`BayNotFound` (404) or :class:`BayTaken` / GoalRejected
        (409, e.g. a robot parked there)."""
        with self._lock:
            candidates = self._ledger.bays.candidates(bay, group)
        refused: list[str] = []
        for choice in candidates:
            try:
                return self.submit(make(choice.pose, choice.name), idempotency_key)
            except (BayTaken, GoalRejected) as exc:
                if bay is not None:
                    raise
                refused.append(f"{choice.name}: {exc}")
        raise BayTaken(f"no free bay in group {group}: " + "; ".join(refused))

    def bays(self) -> list[BayState]:
        """Every bay of the site map with its state (free, reserved, occupied)."""
        with self._lock:
            return self._ledger.bays.states(self._ledger.active, self._roster.views())

    def cancel(self, task_id: str) -> Task:
        """Cancel a task (answered once the cancel is stored); :class:`TaskNotFound`, or
        :class:`TaskConflict` if already final."""
        clock = self._clock
        now, wall = clock.monotonic(), clock.wall()
        with self._lock:
            done = None
            if task_id in self._ledger.active:
                done, effects = self._ledger.cancel(task_id, wall)
                batch = self._queue(effects, now)
        if done is None:
            stored = self._store.get(task_id)
            if stored is None:
                raise TaskNotFound(f"task {task_id} not found")
            raise TaskConflict(f"task {task_id} is already {stored.status.value}")
        self._settle(batch, wait=True)
        self._planner.request("task_finished")
        return done
