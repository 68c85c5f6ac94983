"""The robot's command-to-wheel latency, measured from its drive's response (pure).

A command takes effect some time after it is sent (its *latency*: from the agent's send to
the instant the wheels turn at it; in order, so a command held up holds up the ones behind
it). :class:`LatencyEstimator` bounds it from what the drive measures: the agent tells it
every wheel command it sends (:meth:`~LatencyEstimator.commanded`, agent clock) and every
measurement of the wheel speeds actually turning (:meth:`~LatencyEstimator.measured`, from
the drive's optional ``wheel_speeds()``, :mod:`robot_agent.drive`).

**How.** A measurement at time t_w matches the commands whose wheel speeds it equals within
the actuation error (each wheel within ``tolerance`` x |command| + ``floor`` rad/s). The
command turning at t_w is one of them; commands are applied in order, so

* every command sent up to the *oldest* match took effect by t_w: its latency <= t_w - sent;
* every command sent after the *newest* match had not: its latency > t_w - sent.

The command in effect never goes back, so a measurement whose newest match is older than an
earlier measurement's oldest one is noise beyond the tolerance (a superseded command that
happens to look like the wheels): it is counted as unmatched and changes no bound.

Each command thus gathers an interval (lo, hi] of its latency. Once it is ``horizon_s`` old
it leaves; if its interval is closed and narrow (at most ``resolution_s`` wide: it changed
from the command before it, so the measurements saw it start) it becomes a *sample*
(contradictory bounds, lo > hi, are dropped). The window runs from the ``trim`` quantile of
the samples' lo to the 1 - ``trim`` quantile of their hi, over the last ``max_samples``:
the extremes of what was sampled less a few outliers (a measurement whose noise exceeds the
tolerance can match the wrong command), widened by half the resolution each way (the
rarest latencies may not be among the samples). It is *assumed* to hold the commands to come: the
latency's distribution does not drift faster than the samples follow. Until
``min_samples`` samples are in, or without measurements at all, the window is the
configured [0, ``fallback_s``] (``SafetyConfig.max_latency_s``); a measured window is
clipped to that bound (the sampling's resolution overstates hi by up to a period) unless
the bound is broken (below). Measured on the disturbed
simulated drive (5 % wheel noise, 2 % bias; tolerance 20 %, one control period of 20 ms):
U(50, 150) ms gives about [20, 200] ms, a constant 80 ms [20, 140] ms, none [0, 60] ms.

**A broken assumption.** When more than ``exceed_share`` of the recent verdicts have a
latency certainly above ``fallback_s`` (their lo), the configured bound is wrong:
:attr:`LatencyWindow.exceeded` says so (the agent reports the fault ``latency_exceeded``)
and the window then reaches at least as far as the slowest latency ever certainly seen,
measured or not.

Memory is bounded: at most ``max_pending`` commands awaiting a verdict, ``max_samples``
samples and ``max_samples`` verdicts on the bound. The window is recomputed every ten
verdicts (a fifth of a second at 50 Hz) once there are samples enough.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class LatencyWindow:
    """Command-to-wheel latency bounds [s]: every command acts within [lo, hi] of its send.

    ``measured``: from the drive's response (else the configured fallback);
    ``exceeded``: a latency above the configured bound was measured.
    """

    lo: float
    hi: float
    measured: bool = False
    exceeded: bool = False

    @property
    def nominal(self) -> float:
        """The latency the prediction uses [s]: the middle of the window."""
        return 0.5 * (self.lo + self.hi)

    @property
    def half_width(self) -> float:
        """How far [s] a command's true latency may be from :attr:`nominal`."""
        return 0.5 * (self.hi - self.lo)


@dataclass(slots=True)
class _Pending:
    """A command awaiting its verdict: sent [s], wheels [rad/s], their match tolerances
    [rad/s], latency bounds (lo, hi] [s]."""

    sent: float
    right: float
    left: float
    tol_right: float
    tol_left: float
    lo: float = 0.0
    hi: float = math.inf


class LatencyEstimator:
    """Bounds on this robot's command-to-wheel latency (module docstring).

    ``fallback_s`` [s]: the configured bound (used until measured); ``tolerance``: relative
    wheel error of a match (the actuation error) and ``floor_rad_s`` [rad/s] an absolute one
    (encoder noise at standstill); ``resolution_s`` [s]: widest sample kept (about two
    control periods); ``horizon_s`` [s]: how long a command waits for its verdict.
    """

    def __init__(
        self,
        fallback_s: float,
        *,
        tolerance: float = 0.1,
        floor_rad_s: float = 0.05,
        resolution_s: float = 0.04,
        horizon_s: float | None = None,
        min_samples: int = 20,
        max_samples: int = 200,
        max_pending: int = 512,
        trim: float = 0.01,
        exceed_share: float = 0.1,
    ) -> None:
        if not (math.isfinite(fallback_s) and fallback_s >= 0.0):
            raise ValueError(f"fallback latency must be finite and >= 0, got {fallback_s}")
        self.fallback_s = float(fallback_s)
        self.tolerance = float(tolerance)
        self.floor = float(floor_rad_s)
        self.resolution = float(resolution_s)
        self.horizon = float(horizon_s) if horizon_s is not None else max(1.0, 4.0 * fallback_s)
        self.min_samples = int(min_samples)
        self.trim = float(trim)
        self.exceed_share = float(exceed_share)
        self._pending: deque[_Pending] = deque(maxlen=max_pending)
        self._samples: deque[tuple[float, float]] = deque(maxlen=max_samples)
        self._over: deque[float] = deque(maxlen=max_samples)  # lo of each verdict [s]
        self._worst = 0.0  # [s] the largest latency certainly seen (a lo), ever
        self._window = LatencyWindow(0.0, self.fallback_s)
        self._stale = 0  # verdicts since the window was computed (it is every 10: cheap)
        self.unmatched = 0  # measurements that matched no command (noise beyond tolerance)
        #: [s] send time of the oldest command that may still be turning: commands act in
        #: order, so it never goes back (the oldest match of every measurement taken).
        self._in_effect_from = -math.inf

    # -- inputs -----------------------------------------------------------------------------
    def commanded(self, sent: float, right: float, left: float) -> None:
        """The agent sent wheel speeds ``right``, ``left`` [rad/s] at ``sent`` [s]."""
        right, left = float(right), float(left)
        tol_right = self.tolerance * abs(right) + self.floor
        tol_left = self.tolerance * abs(left) + self.floor
        self._pending.append(_Pending(float(sent), right, left, tol_right, tol_left))

    def measured(self, at: float, right: float, left: float) -> None:
        """The wheels turned at ``right``, ``left`` [rad/s] at ``at`` [s, agent clock]."""
        if not (math.isfinite(at) and math.isfinite(right) and math.isfinite(left)):
            return
        pending = self._pending
        first = last = -1
        for k, entry in enumerate(pending):
            if entry.sent > at:
                break  # sent after the measurement: cannot be the one turning
            if (
                abs(right - entry.right) <= entry.tol_right
                and abs(left - entry.left) <= entry.tol_left
            ):
                if first < 0:
                    first = k
                last = k
        if first < 0 or pending[last].sent < self._in_effect_from:
            # no match, or only commands already superseded: the noise beyond the tolerance
            # made an old command look like the one turning (it would raise the lower bound
            # of every command since, a burst of false samples)
            self.unmatched += 1
        else:
            self._in_effect_from = max(self._in_effect_from, pending[first].sent)
            for k, entry in enumerate(pending):
                since = at - entry.sent
                if k <= first:  # took effect by `at` (the one turning is at or after it)
                    entry.hi = min(entry.hi, since)
                elif k > last:  # not yet in effect (nothing after `last` is turning)
                    entry.lo = max(entry.lo, since)
        self._retire(at)

    def _retire(self, now: float) -> None:
        """Commands older than the horizon leave with their verdict (a sample, or nothing)."""
        pending = self._pending
        changed = False
        while pending and (now - pending[0].sent > self.horizon or len(pending) == pending.maxlen):
            entry = pending.popleft()
            changed = True
            if entry.lo > entry.hi:  # contradictory (a match beyond the tolerance): no verdict
                continue
            self._over.append(entry.lo)
            self._worst = max(self._worst, entry.lo)
            if entry.hi - entry.lo <= self.resolution:
                self._samples.append((entry.lo, entry.hi))
        if changed:
            self._stale += 1
            if self._stale >= 10 or len(self._samples) < 2 * self.min_samples:
                self._stale = 0
                self._window = self._compute()

    # -- output -----------------------------------------------------------------------------
    def _compute(self) -> LatencyWindow:
        over = sorted(self._over)
        cut = int(len(over) * (1.0 - self.exceed_share))
        exceeded = len(over) >= self.min_samples and over[min(cut, len(over) - 1)] > self.fallback_s
        if len(self._samples) >= self.min_samples:
            los = sorted(s[0] for s in self._samples)
            his = sorted(s[1] for s in self._samples)
            k = int(len(los) * self.trim)
            # Half the resolution (a control period) more each way: the rarest latencies
            # (a command held up behind the one before acts late; a fast one is rare)
            # may not be among the samples.
            margin = 0.5 * self.resolution
            lo, hi, measured = max(0.0, los[k] - margin), his[len(his) - 1 - k] + margin, True
        else:
            lo, hi, measured = 0.0, self.fallback_s, False
        if exceeded:  # at least as far as the slowest latency ever certainly seen
            hi = max(hi, self._worst + self.resolution)
        else:  # the configured bound holds until a latency above it is measured
            lo, hi = min(lo, self.fallback_s), min(hi, self.fallback_s)
        return LatencyWindow(lo, hi, measured, exceeded)

    def window(self) -> LatencyWindow:
        """The latency window [s] for the next command (module docstring)."""
        return self._window

    @property
    def samples(self) -> int:
        """Samples held (bounded by ``max_samples``)."""
        return len(self._samples)

    @property
    def pending(self) -> int:
        """Commands awaiting a verdict (bounded by ``max_pending``)."""
        return len(self._pending)
