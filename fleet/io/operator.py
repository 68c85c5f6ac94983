"""Operator commands over Zenoh: build, send (reliably) and confirm a ``ControlCommand``.

Used by ``parkfleet estop | pause | resume`` (a client session of its own: it works while
the fleet service is down), by the fleet service's bus and by ``parkfleet bench estop``.

* :func:`put_control` publishes on ``control`` (whole fleet) or ``robot/<id>/control`` with
  congestion control ``BLOCK`` (never dropped under load, unlike the default ``DROP``),
  priority ``REAL_TIME`` and ``express`` (sent at once, not batched).
* :func:`command` stamps a new command; its ``seq`` is the wall clock in microseconds, so
  one-shot tools that share an issuer name still send increasing sequence numbers.
* :func:`send_and_confirm` sends at once, re-sends the *same* command (same ``seq``:
  harmless repeats) until every robot concerned reports a state that obeys it or ``wait_s``
  passes, and says who confirmed when. The robots concerned are the named one, or every
  robot whose liveliness token a query started *after* the first send finds (plus any robot
  seen obeying): a fleet-wide stop never waits for discovery before it goes out.
"""

from __future__ import annotations

import re
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh

from fleet.core.wire import (
    SERVICE_TOKEN,
    ControlAction,
    ControlCommand,
    Keys,
    RobotState,
    encode,
    obeys,
)
from fleet.io.decoder import Decoder

#: Seconds between re-sends of an unconfirmed command.
RESEND_S = 0.2


def default_issuer(prefix: str = "cli") -> str:
    """``<prefix>-<host name>`` made key-safe (at most 64 characters)."""
    host = re.sub(r"[^A-Za-z0-9_.-]", "-", socket.gethostname()) or "host"
    return f"{prefix}-{host}"[:64]


def command(
    action: ControlAction | str,
    *,
    issuer: str,
    robot_id: str | None = None,
    reason: str | None = None,
    clock: Callable[[], float] = time.time,
) -> ControlCommand:
    """A new command stamped now; ``seq`` = wall clock in microseconds."""
    now = clock()
    return ControlCommand(
        command=ControlAction(action),
        robot_id=robot_id,
        issuer=issuer,
        seq=int(now * 1e6),
        stamp=now,
        reason=reason or None,
    )


def put_control(session: zenoh.Session, keys: Keys, message: ControlCommand) -> None:
    """Publish ``message`` on its key (fleet or robot), never dropped, at top priority."""
    session.put(
        keys.control(message.robot_id),
        encode(message),
        congestion_control=zenoh.CongestionControl.BLOCK,
        priority=zenoh.Priority.REAL_TIME,
        express=True,
    )


def online_robots(session: zenoh.Session, keys: Keys, timeout_s: float = 2.0) -> list[str]:
    """Ids of the robots whose liveliness token is present now (sorted)."""
    found: set[str] = set()
    for reply in session.liveliness().get(keys.all_alive, timeout=timeout_s):
        if reply.ok is None:
            continue
        robot = keys.robot_of(str(reply.ok.key_expr))
        if robot is not None and robot != SERVICE_TOKEN:
            found.add(robot)
    return sorted(found)


@dataclass
class Outcome:
    """Who obeyed a command: robot id -> seconds from the first send to its first obeying
    state (received here), and the robots concerned that did not within the wait.
    ``discovered``: the liveliness query for the robots concerned completed within the wait
    (always true for a command to one robot, false when ``wait_s = 0``)."""

    command: ControlCommand
    confirmed: dict[str, float] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    sends: int = 0
    discovered: bool = False


class _Watch:
    """Who should obey a command and who did (Zenoh callback threads).

    ``robots`` is the robot concerned for a per-robot command; for a fleet-wide one it fills
    with the liveliness tokens the query finds (:meth:`token`) and with every robot whose
    state shows it obeys. Done once discovery completed and every robot concerned obeyed.
    """

    def __init__(self, keys: Keys, action: ControlAction, robot: str | None) -> None:
        self.keys = keys
        self.action = action
        self.robot = robot
        self.robots: set[str] = set() if robot is None else {robot}
        self.discovered = robot is not None
        self.started = time.monotonic()
        self.obeyed: dict[str, float] = {}
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.decoder = Decoder("parkfleet control")

    def _check(self) -> None:  # under self.lock
        if self.discovered and self.robots <= self.obeyed.keys():
            self.done.set()

    def __call__(self, sample: Any) -> None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None or self.keys.robot_of(str(sample.key_expr)) != state.robot_id:
            return
        if self.robot not in (None, state.robot_id) or not obeys(self.action, state.mode):
            return
        with self.lock:
            self.obeyed.setdefault(state.robot_id, time.monotonic() - self.started)
            self.robots.add(state.robot_id)
            self._check()

    def token(self, reply: Any) -> None:
        """A liveliness reply: one more robot concerned."""
        if reply.ok is None:
            return
        robot = self.keys.robot_of(str(reply.ok.key_expr))
        if robot is None or robot == SERVICE_TOKEN:
            return
        with self.lock:
            self.robots.add(robot)
            self._check()

    def discovery_done(self) -> None:
        """The liveliness query completed (every reply in, or its timeout)."""
        with self.lock:
            self.discovered = True
            self._check()


def send_and_confirm(
    session: zenoh.Session, keys: Keys, message: ControlCommand, wait_s: float
) -> Outcome:
    """Send ``message`` at once, then re-send it every ``RESEND_S`` until the robots
    concerned obey (see the module docstring) or ``wait_s`` [s] passes; ``wait_s = 0``
    sends once and waits for nothing.

    The first put goes out before anything else is asked of the network: for a fleet-wide
    command, the liveliness query for the robots concerned runs in the background (its
    replies arrive on Zenoh's threads) while the re-sends go on. The wait ends early only
    once that query completed and every robot it found obeyed; a robot whose obeying state
    arrives is counted confirmed even if its token was not (yet) found. No lock is held
    across a put."""
    outcome = Outcome(message)
    watch = _Watch(keys, message.command, message.robot_id)
    subscriber: Any = session.declare_subscriber(keys.all_states, watch)
    try:
        watch.started = time.monotonic()
        deadline = watch.started + wait_s
        put_control(session, keys, message)
        outcome.sends += 1
        if wait_s > 0 and message.robot_id is None:
            session.liveliness().get(
                keys.all_alive,
                zenoh.handlers.Callback(watch.token, watch.discovery_done),
                timeout=wait_s,
            )
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or watch.done.wait(min(RESEND_S, left)):
                break
            put_control(session, keys, message)
            outcome.sends += 1
    finally:
        subscriber.undeclare()
    with watch.lock:
        outcome.confirmed = dict(sorted(watch.obeyed.items()))
        outcome.missing = sorted(watch.robots - watch.obeyed.keys())
        outcome.discovered = watch.discovered and wait_s > 0
    return outcome
