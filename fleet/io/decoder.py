"""Decoding at the I/O edge: malformed payloads are dropped, logged and counted, never raised.

:class:`Decoder` wraps the pure parsers of :mod:`fleet.core.wire` with thread-safe drop
counters (Zenoh callbacks run on several threads) and sampled log lines;
:class:`CallbackGuard` wraps Zenoh callbacks so an exception is counted and logged (Zenoh
itself prints and swallows it).
"""

from __future__ import annotations

import logging
import threading
from collections import Counter
from collections.abc import Callable
from typing import Any, TypeVar

from pydantic import BaseModel

from fleet.core.wire import (
    CancelAssignment,
    ParkAssignment,
    Payload,
    Rejected,
    parse,
    parse_assignment,
)

_log = logging.getLogger(__name__)
M = TypeVar("M", bound=BaseModel)


def _sampled(count: int) -> bool:
    """Log the first few occurrences, then one in a thousand."""
    return count <= 10 or count % 1000 == 0


class Decoder:
    """Decodes payloads, dropping (and counting) anything malformed instead of raising."""

    def __init__(self, name: str = "parkfleet") -> None:
        self.name = name
        self._lock = threading.Lock()
        self.dropped: Counter[str] = Counter()

    @property
    def dropped_total(self) -> int:
        with self._lock:
            return sum(self.dropped.values())

    def drop(self, reason: str, detail: str) -> None:
        """Count (and log, sampled) a message dropped for ``reason``; also for callers'
        own checks such as a state published on another robot's key."""
        with self._lock:
            self.dropped[reason] += 1
            count = self.dropped[reason]
        if _sampled(count):
            _log.warning(
                "%s: dropped message (%s, %d so far): %s", self.name, reason, count, detail
            )

    def decode(self, model: type[M], payload: Payload) -> M | None:
        """Validate ``payload`` as ``model``; None (and a count) if it is not one."""
        result = parse(model, payload)
        if isinstance(result, Rejected):
            self.drop(result.reason, result.detail)
            return None
        return result

    def decode_assignment(self, payload: Payload) -> ParkAssignment | CancelAssignment | None:
        """Validate a park or cancel assignment; None (and a count) otherwise."""
        result = parse_assignment(payload)
        if isinstance(result, Rejected):
            self.drop(result.reason, result.detail)
            return None
        return result


class CallbackGuard:
    """Wraps Zenoh callbacks: an exception is caught, counted and logged, never lost."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._lock = threading.Lock()
        self.errors = 0

    def wrap(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        def guarded(arg: Any) -> None:
            try:
                fn(arg)
            except Exception:
                with self._lock:
                    self.errors += 1
                    count = self.errors
                if _sampled(count):
                    _log.exception("%s: callback failed (%d so far)", self.name, count)

        return guarded
