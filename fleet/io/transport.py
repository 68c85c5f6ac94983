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

from fleet.core.wire import Keys
from fleet.io.acl import credential_users, fleet_acl
from fleet.io.settings import DEFAULT_ROUTER_ENDPOINT, Settings, ZenohSettings

_log = logging.getLogger(__name__)

Role = Literal["router", "client", "peer"]
LOOPBACK_PREFIXES = ("tcp/127.0.0.1:", "tcp/[::1]:", "tcp/localhost:")


def zenoh_config(settings: ZenohSettings, role: Role) -> zenoh.Config:
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
    usrpwd: dict[str, str] = {}
    if settings.zenoh_user is not None and settings.zenoh_password is not None:
        usrpwd |= {
            "user": settings.zenoh_user,
            "password": settings.zenoh_password.get_secret_value(),
        }
    if settings.zenoh_credentials_file is not None:
        usrpwd["dictionary_file"] = str(settings.zenoh_credentials_file)
    if usrpwd:
        conf.insert_json5("transport/auth/usrpwd", json.dumps(usrpwd))
    if settings.tls_root_ca:
        tls: dict[str, object] = {
            "root_ca_certificate": str(settings.tls_root_ca),
            "verify_name_on_connect": settings.tls_verify_name,
        }
        if settings.tls_cert and settings.tls_key:
            tls |= {
                "listen_certificate": str(settings.tls_cert),
                "listen_private_key": str(settings.tls_key),
                "connect_certificate": str(settings.tls_cert),
                "connect_private_key": str(settings.tls_key),
                "enable_mtls": True,
            }
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    # Access control is the router's job (robots may share the fleet's settings file, and
    # a robot's own settings have no ACL fields at all).
    access_control = None
    if mode == "router" and isinstance(settings, Settings):
        access_control = access_control_json(settings)
    if access_control is not None:
        try:
            conf.insert_json5("access_control", access_control)
        except zenoh.ZError as exc:
            raise ValueError(f"invalid access_control block (acl_file?): {exc}") from exc
    return conf


def access_control_json(settings: Settings) -> str | None:
    """The ``access_control`` block (JSON5 text) the settings ask a router for, or None.

    ``acl_file`` is used verbatim; otherwise ``acl`` generates the fleet policy
    (:func:`fleet.io.acl.fleet_acl`) for ``acl_robot_ids``, or, when that list is empty, for
    every user of ``zenoh_credentials_file`` that is not a service user.
    """
    if settings.acl_file is not None:
        return settings.acl_file.read_text()
    if not settings.acl:
        return None
    robots = list(settings.acl_robot_ids)
    if not robots and settings.zenoh_credentials_file is not None:
        users = credential_users(settings.zenoh_credentials_file.read_text())
        trusted = {*settings.acl_service_users, *settings.acl_operator_users}
        robots = [u for u in users if u not in trusted]
    block = fleet_acl(
        Keys(settings.fleet_name),
        robots,
        service_identities=settings.acl_service_users,
        operator_identities=settings.acl_operator_users,
        identity=settings.acl_identity,
        ros2_namespaces=settings.acl_ros2_namespaces,
        ros2_domain_id=settings.acl_ros2_domain_id,
    )
    return json.dumps(block)


def open_session(settings: ZenohSettings, role: Role) -> zenoh.Session:
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


def tcp_endpoint(locators: list[str]) -> str:
    """The endpoint to connect to among ``locators``: a TCP one, loopback preferred.

    Raises ConnectionError when there is none (a router listening only on TLS, say).
    """
    tcp = [loc for loc in locators if loc.startswith("tcp/")]
    if not tcp:
        raise ConnectionError(f"the Zenoh router has no TCP endpoint robots can reach: {locators}")
    loopback = [loc for loc in tcp if loc.startswith(LOOPBACK_PREFIXES)]
    return (loopback or tcp)[0]
