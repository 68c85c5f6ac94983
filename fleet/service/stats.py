"""The service's counters and its planning-latency window (thread-safe, bounded).

:class:`Counters` are monotonic event counts shown in ``/healthz``; every thread of the
service adds to them. :class:`LatencyWindow` keeps the last ``size`` durations and answers
percentiles (nearest rank) over them.
"""

from __future__ import annotations

import math
import threading
from collections import Counter, deque
from dataclasses import dataclass


class Counters:
    """Named event counts, safe to add to from any thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._counts: Counter[str] = Counter()

    def add(self, key: str, n: int = 1) -> None:
        with self._lock:
            self._counts[key] += n

    def get(self, key: str) -> int:
        with self._lock:
            return self._counts[key]

    def snapshot(self) -> dict[str, int]:
        with self._lock:
            return dict(self._counts)


@dataclass(frozen=True)
class PlannerStats:
    """How planning goes (``/healthz``): latency over the last plans, and what was dropped."""

    plans: int  # plans made since start
    window: int  # plans the percentiles are taken over (the most recent ones)
    p50_ms: float | None  # median planning time [ms] (None before the first plan)
    p99_ms: float | None
    fallbacks: int  # robots held (task waiting) for want of a safe option
    rebased: int  # plans made on a stale snapshot, applied in part
    stale_dropped: int  # plans made on a stale snapshot with nothing left to apply
    decisions_stale_dropped: int  # decisions on tasks that changed meanwhile
    unsafe_dropped: int  # decisions that would start a robot in a plan predicted unsafe
    relaxed: int = 0  # plans made at the standstill margin (no robot could move otherwise)


class LatencyWindow:
    """The last ``size`` durations [s]; percentiles over them."""

    def __init__(self, size: int = 200) -> None:
        self._lock = threading.Lock()
        self._values: deque[float] = deque(maxlen=size)

    def add(self, seconds: float) -> None:
        with self._lock:
            self._values.append(seconds)

    def __len__(self) -> int:
        with self._lock:
            return len(self._values)

    def percentile(self, q: float) -> float | None:
        """The ``q``-th percentile (0 < q <= 100, nearest rank) [s], None when empty."""
        with self._lock:
            values = sorted(self._values)
        if not values:
            return None
        rank = max(1, math.ceil(q / 100.0 * len(values)))
        return values[rank - 1]
