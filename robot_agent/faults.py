"""A robot's structured errors: which faults are active, at what level, since when (pure).

Each tick the agent lists the faults it sees (:func:`current_faults`); :class:`FaultBook`
keeps the time each one began (``since``, the robot's wall clock) for as long as it stays
active, and forgets it when it goes away. They travel in ``RobotState.errors``.

Codes (stable, for scripts and dashboards):

* ``estop`` (fatal) -- an operator's emergency stop is latched; needs a ``release``;
* ``pose_stale`` (error) -- the drive's pose is older than ``pose_stale_s``;
* ``link_lost`` (error) -- the router link is gone (``robot_agent.link``);
* ``drive_error`` (error) -- the drive raised on the last tick (the robot was stopped);
* ``tick_error`` (error) -- the agent's own tick failed (the robot was stopped);
* ``pose_jump`` (error) -- the ros2 drive's odometry jumped or reset: holding until
  re-aligned (any code a drive's optional ``faults()`` reports is passed on like this);
* ``latency_exceeded`` (warning) -- the drive's measured command-to-wheel latency is above
  ``SafetyConfig.max_latency_s``: an assumption of the safety filter is broken; the robot
  drives on, its filter using the measured latency (:mod:`robot_agent.latency`; measured
  with ``SafetyConfig.prediction`` on).
"""

from __future__ import annotations

from collections.abc import Iterable

from fleet.core.wire import MAX_ROBOT_ERRORS, ErrorLevel, RobotError

Fault = tuple[str, ErrorLevel, str]
"""(code, level, message) of a fault seen on one tick."""


def current_faults(
    *,
    pose_age: float,
    pose_stale_s: float,
    link_ok: bool,
    estop: str | None = None,
    failure: tuple[str, str] | None = None,
    drive: Iterable[tuple[str, str]] = (),
    latency: str | None = None,
) -> list[Fault]:
    """Faults of one tick.

    ``pose_age`` [s] of the drive's pose (NaN if unknown), ``estop`` the operator latch's
    detail when e-stopped, ``failure`` ``(code, message)`` when the tick raised,
    ``latency`` what is wrong with the measured latency (None: within its bound).
    """
    faults: list[Fault] = []
    if estop is not None:
        faults.append(("estop", ErrorLevel.FATAL, estop))
    if failure is not None:
        faults.append((failure[0], ErrorLevel.ERROR, failure[1]))
    elif not pose_age <= pose_stale_s:  # also NaN
        faults.append(
            ("pose_stale", ErrorLevel.ERROR, f"own pose older than {pose_stale_s:g} s: holding")
        )
    faults.extend((code, ErrorLevel.ERROR, message) for code, message in drive)
    if not link_ok:
        faults.append(("link_lost", ErrorLevel.ERROR, "link to the fleet network lost: holding"))
    if latency is not None:
        faults.append(("latency_exceeded", ErrorLevel.WARNING, latency))
    return faults


class FaultBook:
    """The active faults of one robot, each with the time it began."""

    def __init__(self) -> None:
        self._active: dict[str, RobotError] = {}
        self._errors: list[RobotError] = []

    def update(self, faults: Iterable[Fault], now: float) -> list[RobotError]:
        """Record this tick's faults at ``now`` [s, wall]; returns the active ones, oldest first.

        A fault keeps its ``since`` while its code stays active at the same level; a fault
        whose message changes keeps it too. Unchanged faults reuse their objects.
        """
        active: dict[str, RobotError] = {}
        changed = False
        for code, level, message in faults:
            old = self._active.get(code)
            if old is not None and old.level is level and old.message == message:
                active[code] = old
                continue
            since = old.since if old is not None and old.level is level else now
            active[code] = RobotError(code=code, level=level, message=message[:200], since=since)
            changed = True
        if changed or active.keys() != self._active.keys():
            self._active = active
            ordered = sorted(active.values(), key=lambda e: e.since)
            self._errors = ordered[:MAX_ROBOT_ERRORS]
        return self._errors
