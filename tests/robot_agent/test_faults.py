"""Structured robot errors: which faults are active, their level, since when."""

from __future__ import annotations

from fleet.core.wire import ErrorLevel
from robot_agent.faults import FaultBook, current_faults


def test_faults_of_a_tick() -> None:
    assert current_faults(pose_age=0.1, pose_stale_s=0.5, link_ok=True) == []
    codes = current_faults(
        pose_age=float("nan"), pose_stale_s=0.5, link_ok=False, estop="emergency stop by ops"
    )
    assert [(c, lvl) for c, lvl, _ in codes] == [
        ("estop", ErrorLevel.FATAL),
        ("pose_stale", ErrorLevel.ERROR),
        ("link_lost", ErrorLevel.ERROR),
    ]
    failed = current_faults(
        pose_age=float("nan"), pose_stale_s=0.5, link_ok=True, failure=("drive_error", "boom")
    )
    assert failed == [("drive_error", ErrorLevel.ERROR, "boom")]  # no pose: not also stale


def test_book_keeps_since_while_a_fault_lasts_and_forgets_it_after() -> None:
    book = FaultBook()
    stale = ("pose_stale", ErrorLevel.ERROR, "old pose")
    link = ("link_lost", ErrorLevel.ERROR, "no router")
    assert book.update([stale], 10.0)[0].since == 10.0
    errors = book.update([stale, link], 11.0)
    assert [(e.code, e.since) for e in errors] == [("pose_stale", 10.0), ("link_lost", 11.0)]
    assert book.update([link], 12.0)[0].code == "link_lost"
    assert book.update([stale, link], 13.0)[-1].since == 13.0  # a new episode
    assert book.update([], 14.0) == []


def test_level_change_restarts_the_fault_and_unchanged_faults_are_reused() -> None:
    book = FaultBook()
    first = book.update([("drive_error", ErrorLevel.ERROR, "x")], 1.0)
    again = book.update([("drive_error", ErrorLevel.ERROR, "x")], 2.0)
    assert again[0] is first[0]
    worse = book.update([("drive_error", ErrorLevel.FATAL, "x")], 3.0)
    assert worse[0].since == 3.0
