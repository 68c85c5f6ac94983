"""``send_and_confirm`` with a fake session: the first put goes out before the liveliness
query for the robots concerned has answered, re-sends go on meanwhile, and the wait ends
once that query completed and every robot it found obeyed."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

from support import FakePayload, FakeSample

from fleet.core.wire import ControlAction, Keys, Pose, RobotMode, RobotState, encode
from fleet.io import operator

KEYS = Keys("yard")


@dataclass
class _Ok:
    key_expr: str


@dataclass
class _Reply:
    ok: _Ok | None


class _Subscriber:
    def undeclare(self) -> None:
        pass


class _SlowLiveliness:
    """A liveliness query that answers only once the session has seen ``puts_first`` puts
    (so it cannot have answered before the first one), on a thread of its own as Zenoh's
    callbacks do."""

    def __init__(self, session: FakeSession, robots: list[str], puts_first: int) -> None:
        self.session = session
        self.robots = robots
        self.puts_first = puts_first
        self.thread: threading.Thread | None = None

    def get(self, key_expr: str, handler: Any, *, timeout: float) -> None:
        assert key_expr == KEYS.all_alive
        self.session.log.append("query")

        def answer() -> None:
            with self.session.changed:
                self.session.changed.wait_for(lambda: self.session.puts >= self.puts_first)
                self.session.log.append("replies")
            for robot in self.robots:
                handler.callback(_Reply(_Ok(f"{KEYS.root}/alive/{robot}")))
            handler.callback(_Reply(None))  # an error reply is ignored
            self.session.log.append("query done")
            handler.drop()

        self.thread = threading.Thread(target=answer, daemon=True)
        self.thread.start()


class FakeSession:
    """Records puts; every put of the command makes the robots in ``obey`` report a state
    that obeys it (as agents do on their next tick)."""

    def __init__(self, robots: list[str], obey: list[str], puts_first: int) -> None:
        self.log: list[str] = []
        self.puts = 0
        self.changed = threading.Condition()
        self.obey = obey
        self.subscriber: Any = None
        self.query = _SlowLiveliness(self, robots, puts_first)

    def liveliness(self) -> _SlowLiveliness:
        return self.query

    def declare_subscriber(self, key_expr: str, callback: Any) -> _Subscriber:
        assert key_expr == KEYS.all_states
        self.subscriber = callback
        return _Subscriber()

    def put(self, key_expr: str, payload: bytes, **_: Any) -> None:
        assert key_expr == KEYS.control()
        with self.changed:
            self.puts += 1
            self.log.append("put")
            self.changed.notify_all()
        for robot in self.obey:
            state = RobotState(
                robot_id=robot, seq=self.puts, stamp=0.0, pose=Pose(x=0, y=0), mode=RobotMode.ESTOP
            )
            self.subscriber(FakeSample(KEYS.state(robot), FakePayload(encode(state))))


def _estop() -> Any:
    return operator.command(ControlAction.ESTOP, issuer="test")


def test_the_first_put_goes_out_before_the_liveliness_query_answers() -> None:
    session = FakeSession(["r1", "r2"], obey=["r1", "r2"], puts_first=2)
    outcome = operator.send_and_confirm(session, KEYS, _estop(), 60.0)  # type: ignore[arg-type]
    assert session.query.thread is not None
    session.query.thread.join()
    # put, then the query; its replies only after a re-send: the robots' confirmation of the
    # first put did not end the wait, the completed discovery did.
    assert session.log[:2] == ["put", "query"]
    assert session.log.index("replies") > session.log.index("put", 2)
    assert outcome.discovered and outcome.missing == []
    assert list(outcome.confirmed) == ["r1", "r2"] and outcome.sends >= 2


def test_a_robot_found_by_the_query_that_does_not_obey_is_missing() -> None:
    session = FakeSession(["r1", "r2"], obey=["r1", "r3"], puts_first=1)
    outcome = operator.send_and_confirm(session, KEYS, _estop(), 0.5)  # type: ignore[arg-type]
    assert outcome.discovered
    assert list(outcome.confirmed) == ["r1", "r3"]  # r3: no token found, seen obeying
    assert outcome.missing == ["r2"]


def test_wait_zero_sends_once_and_asks_nobody() -> None:
    session = FakeSession(["r1"], obey=[], puts_first=1)
    outcome = operator.send_and_confirm(session, KEYS, _estop(), 0.0)  # type: ignore[arg-type]
    assert session.log == ["put"] and outcome.sends == 1
    assert not outcome.discovered and outcome.confirmed == {} and outcome.missing == []


def test_an_operator_command_does_not_wait_for_every_other_commands_imports() -> None:
    """``parkfleet estop`` builds its parser from its own module: numba, matplotlib and the
    paper's code (~2 s of imports) are not loaded before it publishes; ``--help`` of the
    whole tool still lists every command."""
    import subprocess
    import sys

    probe = (
        "import sys\n"
        "from fleet.cli.main import main\n"
        "try:\n"
        "    main(['estop', '--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = ('numba', 'matplotlib', 'fleet.paper.reproduce', 'fleet.bench.fleet')\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip().splitlines()[-1] == "[]"
    full = subprocess.run(
        [sys.executable, "-m", "fleet.cli", "--help"], capture_output=True, text=True, check=True
    ).stdout
    assert all(name in full for name in ("estop", "serve", "reproduce", "bench"))
