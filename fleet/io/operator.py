"""Operator commands over Zenoh: build, send (reliably) and confirm a ``ControlCommand``.

Used by ``parkfleet estop | pause | resume`` (a client session of its own: it works while
the fleet service is down), by the fleet service's bus and by ``parkfleet bench estop``.

* :func:`put_control` publishes on ``control`` (whole fleet) or ``robot/<id>/control`` with
  congestion control ``BLOCK`` (never dropped under load, unlike the default ``DROP``),
  priority ``REAL_TIME`` and ``express`` (sent at once, not batched).
* :func:`command` stamps a new command; its ``seq`` is the wall clock in microseconds, so
  one-shot tools that share an issuer name still send increasing sequence numbers.
* :func:`send_and_confirm` sends, re-sends the *same* command (same ``seq``: harmless
  repeats) until every robot concerned reports a state that obeys it or ``wait_s`` passes,
  and says who confirmed when. The robots concerned are the named one, or every robot whose
  liveliness token is present.
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
    state (received here), and the robots concerned that did not within the wait."""

    command: ControlCommand
    confirmed: dict[str, float] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    sends: int = 0


class _Watch:
    """Collects, per robot, the first state that obeys an action (Zenoh callback thread)."""

    def __init__(self, keys: Keys, action: ControlAction, robots: set[str]) -> None:
        self.keys = keys
        self.action = action
        self.robots = robots
        self.started = time.monotonic()
        self.obeyed: dict[str, float] = {}
        self.lock = threading.Lock()
        self.all_obeyed = threading.Event()
        if not robots:
            self.all_obeyed.set()
        self.decoder = Decoder("parkfleet control")

    def __call__(self, sample: Any) -> None:
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is None or self.keys.robot_of(str(sample.key_expr)) != state.robot_id:
            return
        if state.robot_id not in self.robots or not obeys(self.action, state.mode):
            return
        with self.lock:
            self.obeyed.setdefault(state.robot_id, time.monotonic() - self.started)
            if self.robots <= self.obeyed.keys():
                self.all_obeyed.set()


def send_and_confirm(
    session: zenoh.Session, keys: Keys, message: ControlCommand, wait_s: float
) -> Outcome:
    """Send ``message`` and re-send it every ``RESEND_S`` until the robots concerned obey
    (see the module docstring) or ``wait_s`` [s] passes; ``wait_s = 0`` sends once."""
    outcome = Outcome(message)
    robots = (
        {message.robot_id} if message.robot_id is not None else set(online_robots(session, keys))
    )
    watch = _Watch(keys, message.command, robots)
    subscriber: Any = session.declare_subscriber(keys.all_states, watch)
    try:
        deadline = time.monotonic() + wait_s
        watch.started = time.monotonic()
        while True:
            put_control(session, keys, message)
            outcome.sends += 1
            left = deadline - time.monotonic()
            if left <= 0 or watch.all_obeyed.wait(min(RESEND_S, left)):
                break
    finally:
        subscriber.undeclare()
    with watch.lock:
        outcome.confirmed = dict(sorted(watch.obeyed.items()))
    outcome.missing = sorted(robots - outcome.confirmed.keys())
    return outcome
