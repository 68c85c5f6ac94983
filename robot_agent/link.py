"""Is a robot still in touch with the fleet's Zenoh network? (``Settings.link_timeout_s``)

A robot that cannot see its peers cannot avoid them: when its link to the router is lost
it must stop (mode ``holding``) and resume, from where it is, once the link returns. That
is different from the fleet *service* being gone while the router and the peers are still
visible: then the robot keeps finishing its goal (shared/DESIGN.md).

:class:`LinkMonitor` judges the link from three kinds of evidence, polled from the
control loop (cheap; at most every ``probe_interval`` real seconds):

* the session's own report: a ``client`` session with no router left
  (``session.info.routers_zid()`` empty) has lost its link; Zenoh sees a closed TCP
  connection at once and a silent one after the transport lease (``Settings.lease_ms``);
* traffic heard through the router within ``link_timeout_s``: a remote peer state
  (:attr:`robot_agent.world_feed.WorldFeed.last_heard`), the fleet service's liveliness token
  appearing, or the reply to an echo query sent to the router's admin space
  (``@/<router zid>/router``) every ``link_timeout_s / 3``. The echo lets a lone robot
  with no peers and no service keep its link; a router without an admin space gives no
  echo, and then peers or the service must be heard;
* without a session (unit tests) the link is always up.

Times are ``time.monotonic()`` seconds (real time, also under a time-scaled simulation:
a network link does not run faster with the simulation).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from fleet.core.wire import Keys

_log = logging.getLogger(__name__)


def link_is_up(now: float, last_heard: float, router_connected: bool, timeout_s: float) -> bool:
    """Pure rule: the router is connected and something was heard within ``timeout_s``."""
    return router_connected and now - last_heard <= timeout_s


class LinkMonitor:
    """Tracks the link of one session (shared by every agent on it, see ``SimFleet``)."""

    def __init__(
        self,
        session: Any,
        keys: Keys,
        timeout_s: float,
        *,
        check_router: bool = True,
        clock: Callable[[], float] = time.monotonic,
        heard_elsewhere: Callable[[], float] | None = None,
    ) -> None:
        self.session = session
        self.keys = keys
        self.timeout_s = float(timeout_s)
        self.check_router = check_router
        self.clock = clock
        self._heard_elsewhere = heard_elsewhere
        self.probe_interval = min(0.05, self.timeout_s / 4)
        self.echo_interval = self.timeout_s / 3
        self._lock = threading.Lock()
        now = clock()
        self._last_heard = now
        self._last_poll = float("-inf")
        self._last_echo = float("-inf")
        self._router_connected = True
        self._up = True
        self.losses = 0  # times the link was judged lost
        self.errors = 0
        self._handles: list[Any] = []

    def heard(self) -> None:
        """Something arrived through the network (thread-safe)."""
        now = self.clock()
        with self._lock:
            self._last_heard = max(self._last_heard, now)

    def attach(self) -> None:
        """Watch the service's liveliness token (its appearance counts as traffic)."""
        if self.session is None:
            return
        self._handles.append(
            self.session.liveliness().declare_subscriber(
                self.keys.service_alive, lambda sample: self.heard(), history=True
            )
        )

    def detach(self) -> None:
        handles, self._handles = self._handles, []
        for handle in handles:
            try:
                handle.undeclare()
            except Exception:
                _log.debug("undeclare failed", exc_info=True)

    def _on_echo(self, reply: Any) -> None:
        if getattr(reply, "ok", None) is not None:
            self.heard()

    def _poll(self, now: float) -> None:
        routers: list[Any] = []
        try:
            routers = list(self.session.info.routers_zid())
        except Exception:
            self.errors += 1
            _log.debug("routers_zid failed", exc_info=True)
        self._router_connected = bool(routers) or not self.check_router
        if routers and now - self._last_echo >= self.echo_interval:
            self._last_echo = now
            try:
                self.session.get(f"@/{routers[0]}/router", self._on_echo, timeout=self.timeout_s)
            except Exception:
                self.errors += 1
                _log.debug("echo query failed", exc_info=True)

    def ok(self) -> bool:
        """Whether the link is up now (polls the session at most every ``probe_interval``)."""
        if self.session is None:
            return True
        now = self.clock()
        if now - self._last_poll >= self.probe_interval:
            self._last_poll = now
            self._poll(now)
        if self._heard_elsewhere is not None:
            elsewhere = self._heard_elsewhere()
            with self._lock:
                self._last_heard = max(self._last_heard, elsewhere)
        with self._lock:
            last = self._last_heard
        up = link_is_up(now, last, self._router_connected, self.timeout_s)
        if up != self._up:
            self._up = up
            if up:
                _log.warning("link to the fleet network is back: resuming")
            else:
                self.losses += 1
                _log.warning(
                    "link to the fleet network lost (%s): holding",
                    "no router" if not self._router_connected else "nothing heard",
                )
        return up
