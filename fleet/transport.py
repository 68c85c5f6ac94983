"""Zenoh plumbing in one place: the config builder and session helpers.

Defaults (shared/DESIGN.md): the fleet host is a ``router`` listening on
``tcp/127.0.0.1:7447``; agents are ``client`` sessions connecting to it; multicast
scouting is off everywhere; the transport lease is short so a hung robot is seen gone.
"""

from __future__ import annotations

import json
import logging
from typing import Literal

import zenoh

from fleet.settings import DEFAULT_ROUTER_ENDPOINT, Settings

_log = logging.getLogger(__name__)

Role = Literal["router", "client", "peer"]


def zenoh_config(settings: Settings, role: Role) -> zenoh.Config:
    """Build the ``zenoh.Config`` for an entry point.

    ``role`` is the default mode (``router`` for the fleet host and ``parkfleet router``,
    ``client`` for agents and tools); ``settings.zenoh_mode`` overrides it. A router with
    no ``listen`` endpoint listens on the default endpoint; a client with no ``connect``
    endpoint connects to it.
    """
    mode = settings.zenoh_mode or role
    listen = list(settings.listen)
    connect = list(settings.connect)
    if mode == "router" and not listen:
        listen = [DEFAULT_ROUTER_ENDPOINT]
    if mode == "client" and not connect:
        connect = [DEFAULT_ROUTER_ENDPOINT]

    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("adminspace/enabled", "true")
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    conf.insert_json5("transport/link/tx/lease", str(settings.lease_ms))
    # Keep trying the router for ever, but report failure fast on the first attempt.
    if mode == "client":
        conf.insert_json5("connect/timeout_ms", "2000")
    if settings.zenoh_user and settings.zenoh_password:
        conf.insert_json5(
            "transport/auth/usrpwd",
            json.dumps(
                {
                    "user": settings.zenoh_user,
                    "password": settings.zenoh_password.get_secret_value(),
                }
            ),
        )
    if settings.tls_root_ca:
        tls: dict[str, object] = {"root_ca_certificate": str(settings.tls_root_ca)}
        if settings.tls_cert and settings.tls_key:
            tls |= {
                "listen_certificate": str(settings.tls_cert),
                "listen_private_key": str(settings.tls_key),
                "connect_certificate": str(settings.tls_cert),
                "connect_private_key": str(settings.tls_key),
                "enable_mtls": True,
            }
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    return conf


def open_session(settings: Settings, role: Role) -> zenoh.Session:
    """Open a session; raises ``ConnectionError`` with a clear message if no router answers."""
    conf = zenoh_config(settings, role)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        where = ", ".join(settings.connect or settings.listen) or DEFAULT_ROUTER_ENDPOINT
        raise ConnectionError(
            f"cannot open a Zenoh {settings.zenoh_mode or role} session ({where}): {exc}. "
            "Is the fleet host (parkfleet serve / parkfleet router) running?"
        ) from exc


def listening_locators(session: zenoh.Session) -> list[str]:
    """Endpoints this session really listens on (resolves a ``:0`` port), via the admin space."""
    zid = session.info.zid()
    for reply in session.get(f"@/{zid}/*"):
        if reply.ok is None:
            continue
        try:
            info = json.loads(reply.ok.payload.to_bytes())
        except ValueError:
            continue
        locators = info.get("locators") if isinstance(info, dict) else None
        if isinstance(locators, list):
            return [str(loc) for loc in locators]
    return []
