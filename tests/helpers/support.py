"""Helpers shared by the test modules (importable as ``support``; see pytest ``pythonpath``)."""

from __future__ import annotations

import select
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from fleet.core.params import Gains, Tolerance
from fleet.core.types import Law, Posture
from fleet.core.wire import Keys, ParkAssignment, Pose, RobotState, encode
from fleet.io.decoder import Decoder
from fleet.io.settings import Settings
from fleet.io.transport import open_session
from fleet.service.fleet_service import FleetService
from fleet.service.host import open_fleet
from fleet.service.store import SqliteTaskStore

#: Gains and tolerance of the hand-made assignments in the tests.
TEST_GAINS = Gains(kx=1.0, ky=2.0, ktheta=1.0)
TEST_TOLERANCE = Tolerance(position=0.1, heading=0.1)


def wait_for(predicate: Callable[[], bool], timeout: float, what: str, poll: float = 0.01) -> None:
    """Poll ``predicate`` every ``poll`` [s] until true; fail the test after ``timeout`` [s]
    naming ``what``. The timeout only bounds a hung test: make it generous (the machine is
    shared), never a measure of speed. A predicate may act too (re-send until received)."""
    end = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(poll)


def child_pids(pid: int) -> set[int]:
    """The process ids of ``pid``'s children (all its threads')."""
    found: set[int] = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        found |= {int(p) for p in (task / "children").read_text().split()}
    return found


def command_line(pid: int) -> str:
    """A process's command line, words joined by spaces ("" once it is gone)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except FileNotFoundError:
        return ""


def is_alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def read_line(proc: subprocess.Popen[bytes], timeout: float) -> str:
    """One line of a child's stdout, or fail the test after ``timeout`` [s]."""
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    if not ready:
        raise AssertionError(f"no output from {proc.args!r} within {timeout} s")
    return proc.stdout.readline().decode()


def park(
    robot_id: str = "r1",
    task_id: str = "t1",
    goal: Posture = (3.0, 0.0, 0.0),
    law: Law = "ccw",
    **fields: Any,
) -> ParkAssignment:
    """A ParkAssignment with the tests' gains and tolerance (``fields`` override the rest)."""
    return ParkAssignment(
        robot_id=robot_id,
        task_id=task_id,
        goal=Pose(x=goal[0], y=goal[1], theta=goal[2]),
        law=law,
        gains=fields.pop("gains", TEST_GAINS),
        tolerance=fields.pop("tolerance", TEST_TOLERANCE),
        **fields,
    )


@contextmanager
def zenoh_fleet_service(settings: Settings, db: Path) -> Iterator[FleetService]:
    """The fleet service in this process: client session, Zenoh bus, SQLite store at ``db``;
    closed (service, session, store) on exit."""
    with (
        open_session(settings, "client") as session,
        open_fleet(settings, session=session, store=lambda _: SqliteTaskStore(db)) as fleet,
    ):
        yield fleet.service


class StateWatcher:
    """Records every RobotState seen on the fleet's state keys (from a separate session)."""

    def __init__(self, session: Any, keys: Keys | None = None) -> None:
        self.decoder = Decoder("watcher")
        self.lock = threading.Lock()
        self.history: dict[str, list[RobotState]] = {}
        self.sub = session.declare_subscriber((keys or Keys()).all_states, self._on)

    def _on(self, sample: Any) -> None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is not None:
            with self.lock:
                self.history.setdefault(state.robot_id, []).append(state)

    def latest(self, rid: str) -> RobotState | None:
        with self.lock:
            states = self.history.get(rid)
            return states[-1] if states else None

    def since(self, rid: str, seq: int) -> list[RobotState]:
        with self.lock:
            return [s for s in self.history.get(rid, []) if s.seq > seq]

    def close(self) -> None:
        self.sub.undeclare()


def assign_until_acked(
    session: Any, watcher: StateWatcher, message: ParkAssignment, timeout: float = 10.0
) -> None:
    """Re-send an assignment until the robot's state carries its task id (the protocol)."""

    def acked() -> bool:
        state = watcher.latest(message.robot_id)
        if state is not None and state.task_id == message.task_id:
            return True
        session.put(Keys().assignment(message.robot_id), encode(message))
        return False

    wait_for(acked, timeout, f"{message.robot_id} to acknowledge {message.task_id}", poll=0.05)


@dataclass
class FakePayload:
    """A Zenoh payload stand-in for callbacks under unit test."""

    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class FakeSample:
    """A Zenoh sample stand-in: key, payload and kind (a put unless told)."""

    key_expr: str
    payload: FakePayload
    kind: Any = field(default_factory=lambda: zenoh.SampleKind.PUT)
