"""Stuck robots: no progress towards the goal for ``Settings.stuck_after_s`` (pure).

:class:`StuckWatch` keeps, per task under way, the smallest *remaining distance* seen --
position error plus heading error times ``heading_arm`` [m] (a robot turning on the spot
near its goal is making progress too) -- and when it last shrank by ``min_progress_m``.
The window runs on two clocks and the first to run out counts: the service's (monotonic)
and the robot's own (its state's ``seq`` over the control rate), so a time-scaled
simulation is judged like a real robot -- ``stuck_after_s`` of driving, not of wall time.
A task whose robot is held on purpose (paused, e-stopped, waiting for the planner) has its
window restarted: standing still then is not being stuck. :meth:`StuckWatch.observe` runs
for every state of a robot under way (the service's hot path): it measures the distance at
most every ``check_interval_s`` [s], and otherwise only notes that the robot was heard.

:func:`stuck_cause` names what the service can see: no pose (no state for the whole
window), a peer within the peer influence radius, a static obstacle within its influence
zone. :data:`RECOVERIES` is the order the service tries (each attempt stored in the task's
history and counted): re-plan with the other law and, on a route, off it (flip), wait a
while (a start delay, so the peer passes), requeue to another robot; after the last the
task fails.

**Standoffs** are found sooner, on the robots' own clock: a robot that reports ``avoiding``
(its safety filter or the repulsion of Eq. (27) acts) and has not come ``standoff_progress_m``
nearer its goal in ``standoff_after_s`` robot seconds (its state's ``seq`` over the control
rate, so a time-scaled simulation is judged like a real robot; a robot held off creeps and
dithers, and a few centimetres of that are no way out) is in a standoff with the robots near
it -- typically two robots nose to nose, each one's filter holding it off the other.
:meth:`StuckWatch.standoff` lists it; the service breaks each standoff by making one robot
give way (:meth:`fleet.service.ledger.TaskLedger.break_standoff`) -- or, when the robot it
is held off by is held by the plan until a zone it holds is free, by routing it round that
one (:meth:`~fleet.service.ledger.TaskLedger.stands_aside`) -- and restarts the windows of the
others (:meth:`StuckWatch.restart`). A robot alone by a post gets its first stuck recovery
after a shorter window of the same kind (``post_stall_after_s``: no peer there will move
away).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from fleet.core.tasks import RobotView
from fleet.core.wire import Obstacle, Pose

RECOVERIES = ("flip", "wait", "requeue")


@dataclass(slots=True)
class _Progress:
    best: float
    since: float  # [s, monotonic] when ``best`` last shrank by min_progress_m
    seen: float  # [s, monotonic] last state of the task's robot
    checked: float = -math.inf  # [s, monotonic] last distance measured
    left: float = math.inf  # [m] the remaining distance last measured (inf: none yet)
    attempts: int = 0
    #: the standoff window, on the robot's clock [s]: its best distance, when that last
    #: shrank, its time at its last state, and whether it then reported ``avoiding``
    robot_best: float = math.inf
    robot_since: float = math.nan
    robot_now: float = math.nan
    avoiding: bool = False
    #: the stuck window on the robot's clock [s]: its best distance, when that last shrank
    stuck_best: float = math.inf
    stuck_since: float = math.nan


def remaining(pose: Pose, goal: Pose, heading_arm: float) -> float:
    """Position error [m] plus the wrapped heading error [rad] times ``heading_arm`` [m]."""
    dtheta = math.atan2(math.sin(goal.theta - pose.theta), math.cos(goal.theta - pose.theta))
    return math.hypot(goal.x - pose.x, goal.y - pose.y) + heading_arm * abs(dtheta)


class StuckWatch:
    """Progress of every task under way (see the module docstring)."""

    def __init__(
        self,
        stuck_after_s: float,
        min_progress_m: float = 0.05,
        heading_arm: float = 0.2,
        check_interval_s: float = 0.25,
        standoff_after_s: float = math.inf,
        standoff_progress_m: float = 0.05,
    ) -> None:
        self.stuck_after_s = stuck_after_s
        self.standoff_after_s = standoff_after_s
        self.standoff_progress_m = standoff_progress_m
        self.min_progress_m = min_progress_m
        self.heading_arm = heading_arm
        self.check_interval_s = check_interval_s
        self._tasks: dict[str, _Progress] = {}

    def __len__(self) -> int:
        return len(self._tasks)

    def observe(
        self,
        task_id: str,
        pose: Pose,
        goal: Pose,
        now: float,
        held: bool,
        robot_t: float = math.nan,
        avoiding: bool = False,
    ) -> None:
        """A state of the task's robot at ``now`` [s, monotonic], ``robot_t`` [s] on the
        robot's own clock (NaN: unknown, no standoff window); ``held``: it stands still on
        purpose (the windows restart); ``avoiding``: it reported ``avoiding``."""
        progress = self._tasks.get(task_id)
        if progress is None:
            progress = self._tasks[task_id] = _Progress(math.inf, now, now)
        progress.seen = now
        self._observe_standoff(progress, pose, goal, held, robot_t, avoiding)
        if held:
            progress.best, progress.since = math.inf, now
            return
        if now - progress.checked < self.check_interval_s:
            return
        progress.checked = now
        left = progress.left = remaining(pose, goal, self.heading_arm)
        if left < progress.best - self.min_progress_m:
            progress.best, progress.since = left, now

    def _observe_standoff(
        self, p: _Progress, pose: Pose, goal: Pose, held: bool, robot_t: float, avoiding: bool
    ) -> None:
        """The standoff window and the stuck window on the robot's clock (a clock that went
        back, a restarted robot, restarts both)."""
        p.avoiding = avoiding
        if math.isnan(robot_t):
            return
        restarted = not robot_t >= p.robot_now  # also the first state (NaN)
        p.robot_now = robot_t
        left = remaining(pose, goal, self.heading_arm)
        if held or restarted or left < p.robot_best - self.standoff_progress_m:
            p.robot_best, p.robot_since = left, robot_t
        if held or restarted or left < p.stuck_best - self.min_progress_m:
            p.stuck_best, p.stuck_since = left, robot_t

    def standoff(self, task_id: str, after_s: float | None = None) -> bool:
        """The task's robot reports ``avoiding`` and has not come ``standoff_progress_m``
        nearer its goal for ``after_s`` (default ``standoff_after_s``) on its own clock."""
        p = self._tasks.get(task_id)
        window = self.standoff_after_s if after_s is None else after_s
        return p is not None and p.avoiding and p.robot_now - p.robot_since >= window

    def restart(self, task_id: str) -> None:
        """A fresh standoff window for the task (another robot gave way)."""
        p = self._tasks.get(task_id)
        if p is not None:
            p.robot_best, p.robot_since = math.inf, p.robot_now

    def start(self, task_id: str, now: float) -> None:
        """The task got (again) a robot at ``now``: a fresh window, attempts kept."""
        progress = self._tasks.get(task_id)
        if progress is None:
            self._tasks[task_id] = _Progress(math.inf, now, now)
        else:
            progress.best, progress.since, progress.seen = math.inf, now, now
            progress.checked = -math.inf
            progress.robot_best, progress.robot_since = math.inf, progress.robot_now
            progress.stuck_best, progress.stuck_since = math.inf, progress.robot_now

    def stuck(self, task_id: str, now: float) -> bool:
        """No progress for ``stuck_after_s`` on the service's clock (``now`` [s, monotonic])
        or on the robot's."""
        p = self._tasks.get(task_id)
        return p is not None and (
            now - p.since >= self.stuck_after_s or p.robot_now - p.stuck_since >= self.stuck_after_s
        )

    def silent(self, task_id: str, now: float) -> bool:
        """No state of the task's robot for the whole window."""
        progress = self._tasks.get(task_id)
        return progress is not None and now - progress.seen >= self.stuck_after_s

    def next_recovery(self, task_id: str, now: float) -> str | None:
        """Record an attempt and return it (``RECOVERIES`` in order), or None: give up."""
        progress = self._tasks[task_id]
        progress.since = now  # the next attempt after another full window
        progress.best, progress.checked = math.inf, -math.inf
        progress.stuck_best, progress.stuck_since = math.inf, progress.robot_now
        if progress.attempts >= len(RECOVERIES):
            return None
        progress.attempts += 1
        return RECOVERIES[progress.attempts - 1]

    def left(self, task_id: str) -> float:
        """The task's remaining distance [m] (:func:`remaining`) when last measured, at most
        ``check_interval_s`` old while its robot drives (inf: never measured)."""
        progress = self._tasks.get(task_id)
        return math.inf if progress is None else progress.left

    def attempts(self, task_id: str) -> int:
        progress = self._tasks.get(task_id)
        return 0 if progress is None else progress.attempts

    def forget(self, task_id: str) -> None:
        self._tasks.pop(task_id, None)


def stuck_cause(
    robot: RobotView | None,
    silent: bool,
    peers: Iterable[RobotView],
    obstacles: Iterable[Obstacle],
    peer_radius: float,
    window_s: float,
) -> str:
    """What the service sees around a stuck robot (see the module docstring)."""
    if robot is None or silent:
        return f"no pose: nothing heard from the robot for {window_s:g} s"
    if robot.detail == "pose stale":
        return "no pose: the robot's own pose is stale"
    p = robot.pose
    near = [
        (math.hypot(o.pose.x - p.x, o.pose.y - p.y), o.robot_id)
        for o in peers
        if o.robot_id != robot.robot_id
    ]
    near = [(d, rid) for d, rid in near if d <= peer_radius]
    if near:
        d, rid = min(near)
        return f"a peer in the way: {rid} at {d:.2f} m"
    for o in obstacles:
        d = math.hypot(o.x - p.x, o.y - p.y)
        if d <= o.radius:
            return f"an obstacle in the way: the one at ({o.x:g}, {o.y:g}), {d:.2f} m"
    return f"no progress for {window_s:g} s (no peer or obstacle near)"
