"""What lives when the server is up is kept out of Python's collections; what comes later
is collected as before (fleet.io.heap.freeze_startup_heap)."""

from __future__ import annotations

import gc
import weakref
from collections.abc import Iterator

import pytest

from fleet.io.heap import freeze_startup_heap


@pytest.fixture
def frozen() -> Iterator[None]:
    yield
    gc.unfreeze()  # the rest of the test session collects as usual


def _collected(obj: object) -> bool:
    """Whether a collection would walk ``obj`` (frozen objects are in no generation)."""
    return any(o is obj for o in gc.get_objects())


def test_objects_alive_at_startup_are_frozen_and_later_ones_are_not(frozen: None) -> None:
    startup = [{"kept": "for the server's life"}]
    assert _collected(startup)
    count = freeze_startup_heap()
    later = [{"made": "by a request"}]
    assert count == gc.get_freeze_count() > 0
    assert not _collected(startup)
    assert _collected(later)


def test_the_collector_stays_on_and_frees_a_cycle_made_after_startup(frozen: None) -> None:
    freeze_startup_heap()
    assert gc.isenabled()

    class Node:
        other: object

    a, b = Node(), Node()
    a.other, b.other = b, a
    gone = weakref.ref(a)
    del a, b
    gc.collect()
    assert gone() is None
