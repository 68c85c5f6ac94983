"""The operator latch: pause / resume, the e-stop latch, per-issuer ordering (pure)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from fleet.core.wire import MAX_ISSUERS, ControlAction, ControlCommand, RobotMode
from robot_agent.operator import OperatorLatch


def cmd(
    action: str, seq: int, issuer: str = "ops", robot_id: str | None = None, reason: str = ""
) -> ControlCommand:
    return ControlCommand(
        command=ControlAction(action),
        robot_id=robot_id,
        issuer=issuer,
        seq=seq,
        stamp=1000.0 + seq,
        reason=reason or None,
    )


def test_pause_holds_until_resume() -> None:
    latch = OperatorLatch("r1")
    assert latch.mode is None and latch.detail is None
    assert latch.apply(cmd("pause", 1, reason="shift change"))
    assert latch.mode is RobotMode.PAUSED
    assert latch.detail == "paused by ops: shift change"
    assert latch.apply(cmd("resume", 2))
    assert latch.mode is None


def test_estop_latches_until_release_and_wins_over_pause() -> None:
    latch = OperatorLatch("r1")
    latch.apply(cmd("pause", 1))
    latch.apply(cmd("estop", 2, issuer="dashboard"))
    assert latch.mode is RobotMode.ESTOP
    assert latch.detail == "emergency stop by dashboard"
    latch.apply(cmd("resume", 3))  # resume does not clear an e-stop
    assert latch.mode is RobotMode.ESTOP
    latch.apply(cmd("pause", 4))
    latch.apply(cmd("release", 5, issuer="dashboard"))
    assert latch.mode is RobotMode.PAUSED  # release clears the e-stop only
    latch.apply(cmd("resume", 6))
    assert latch.mode is None


def test_repeats_and_reordered_commands_of_one_issuer_are_ignored() -> None:
    latch = OperatorLatch("r1")
    assert latch.apply(cmd("estop", 10))
    assert not latch.apply(cmd("estop", 10))  # repeat
    assert latch.apply(cmd("release", 11))
    assert not latch.apply(cmd("estop", 10))  # late copy of the older e-stop
    assert latch.mode is None
    assert latch.applied == 2 and latch.ignored == 2
    # Another issuer has its own sequence.
    assert latch.apply(cmd("estop", 1, issuer="other"))
    assert latch.mode is RobotMode.ESTOP


def test_commands_for_other_robots_are_ignored() -> None:
    latch = OperatorLatch("r1")
    assert not latch.apply(cmd("estop", 1, robot_id="r2"))
    assert latch.mode is None
    assert latch.apply(cmd("estop", 2, robot_id="r1"))
    assert latch.mode is RobotMode.ESTOP


def test_issuers_remembered_are_bounded() -> None:
    latch = OperatorLatch("r1")
    for i in range(MAX_ISSUERS + 10):
        latch.apply(cmd("pause", 5, issuer=f"tool-{i}"))
    assert len(latch._order) == MAX_ISSUERS


commands = st.lists(
    st.tuples(st.sampled_from(list(ControlAction)), st.integers(0, 20)), max_size=30
)


@given(commands)
def test_the_outcome_of_one_issuer_depends_only_on_its_newest_commands(
    sent: list[tuple[ControlAction, int]],
) -> None:
    """Delivering every command twice, in any order the seqs allow, ends as delivering the
    accepted (strictly increasing seq) subsequence once: repeats change nothing."""
    once = OperatorLatch("r1")
    twice = OperatorLatch("r1")
    for action, seq in sent:
        once.apply(cmd(action.value, seq))
        twice.apply(cmd(action.value, seq))
        twice.apply(cmd(action.value, seq))
    assert (once.paused, once.estop) == (twice.paused, twice.estop)
    # The e-stop state is the last accepted estop/release, replayed in seq order.
    accepted: list[tuple[ControlAction, int]] = []
    for action, seq in sent:
        if not accepted or seq > accepted[-1][1]:
            accepted.append((action, seq))
    latches = [a for a, _ in accepted if a in (ControlAction.ESTOP, ControlAction.RELEASE)]
    assert once.estop == (bool(latches) and latches[-1] is ControlAction.ESTOP)
