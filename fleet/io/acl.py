"""Zenoh access control for a fleet: who may publish, subscribe and query which keys.

Pure module (no Zenoh import, no file access): :func:`fleet_acl` builds the
``access_control`` block of a router's Zenoh config from the fleet's key layout
(:class:`fleet.core.wire.Keys`), the robot ids and the trusted service identities.

The policy is *default deny*. A connecting session is recognised by its usrpwd username
or by the common name of its TLS client certificate (``identity``):

* a **robot** ``<id>`` (identity equal to its robot id) may publish only its own state
  ``robot/<id>/state`` and declare only its own liveliness token ``alive/<id>``; it may
  subscribe to every robot's state, to the obstacles and to its own assignments, query the
  obstacles and watch the ``alive/*`` tokens. The router forwards to it only peers' states,
  the obstacles and its *own* assignments;
* a **service** identity (the fleet service when it runs apart from the router, other
  routers of a mesh, operators' tools) may do everything: only a service sends
  assignments;
* anyone else is refused everything (and, with usrpwd, cannot connect at all).

The rules apply where the router sees the message: a ``put`` on another robot's state or
on any assignment key from a robot is dropped at the router's ingress.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, Literal

from fleet.core.wire import Keys, validate_id

Identity = Literal["username", "cert_common_name"]

#: Every message kind Zenoh 1.x access control filters.
ALL_MESSAGES: tuple[str, ...] = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
)

_SUBJECT_FIELD: dict[Identity, str] = {
    "username": "usernames",
    "cert_common_name": "cert_common_names",
}


def _rule(
    rule_id: str, flow: Literal["ingress", "egress"], messages: Sequence[str], keys: Sequence[str]
) -> dict[str, Any]:
    return {
        "id": rule_id,
        "permission": "allow",
        "flows": [flow],
        "messages": list(messages),
        "key_exprs": list(keys),
    }


def fleet_acl(
    keys: Keys,
    robot_ids: Iterable[str],
    *,
    service_identities: Iterable[str] = ("fleet",),
    identity: Identity = "username",
) -> dict[str, Any]:
    """The ``access_control`` config block (a JSON-ready dict) for one fleet's router.

    Parameters
    ----------
    keys
        Key layout of the fleet (``parkfleet/<fleet>/...``).
    robot_ids
        Robots allowed on the fleet; each robot's identity (username or certificate common
        name) must equal its robot id. Ids are validated: wildcards are rejected, so no
        robot can be granted another robot's keys by pattern.
    service_identities
        Identities granted everything (fleet service, meshed routers, operators' tools).
    identity
        What a subject matches: ``username`` (``transport/auth/usrpwd``) or
        ``cert_common_name`` (mutual TLS client certificate).

    Raises
    ------
    ValueError
        On an invalid or duplicate id, or an id that is both a robot and a service.
    """
    robots = [validate_id(r) for r in robot_ids]
    services = [validate_id(s, "service identity") for s in service_identities]
    if len(set(robots)) != len(robots):
        raise ValueError("duplicate robot id in the access-control list")
    both = sorted(set(robots) & set(services))
    if both:
        raise ValueError(f"ids both robot and service in the access-control list: {both}")
    field = _SUBJECT_FIELD[identity]

    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []

    if services:
        rules += [
            _rule("service-in", "ingress", ALL_MESSAGES, ["**"]),
            _rule("service-out", "egress", ALL_MESSAGES, ["**"]),
        ]
        subjects.append({"id": "service", field: services})
        policies.append(
            {"id": "service", "rules": ["service-in", "service-out"], "subjects": ["service"]}
        )

    if robots:
        shared = [
            # What every robot may ask for ...
            _rule(
                "robots-subscribe",
                "ingress",
                ["declare_subscriber"],
                [keys.all_states, keys.obstacles],
            ),
            _rule("robots-query", "ingress", ["query"], [keys.obstacles]),
            _rule(
                "robots-watch-alive",
                "ingress",
                ["declare_liveliness_subscriber", "liveliness_query"],
                [keys.all_alive],
            ),
            # ... and what the router may forward to it.
            _rule("robots-receive", "egress", ["put"], [keys.all_states, keys.obstacles]),
            _rule("robots-replies", "egress", ["reply"], [keys.obstacles, keys.all_alive]),
            _rule("robots-alive", "egress", ["liveliness_token"], [keys.all_alive]),
            # Declarations carry no data; clients use them to filter their own writes.
            _rule(
                "robots-declarations",
                "egress",
                ["declare_subscriber", "declare_queryable"],
                [f"{keys.root}/**"],
            ),
        ]
        rules += shared
        shared_ids = [r["id"] for r in shared]
        for robot in robots:
            own = [
                _rule(f"robot-{robot}-state", "ingress", ["put"], [keys.state(robot)]),
                _rule(f"robot-{robot}-token", "ingress", ["liveliness_token"], [keys.alive(robot)]),
                _rule(
                    f"robot-{robot}-orders",
                    "ingress",
                    ["declare_subscriber"],
                    [keys.assignment(robot)],
                ),
                _rule(f"robot-{robot}-assignment", "egress", ["put"], [keys.assignment(robot)]),
            ]
            rules += own
            subjects.append({"id": f"robot-{robot}", field: [robot]})
            policies.append(
                {
                    "id": f"robot-{robot}",
                    "rules": shared_ids + [r["id"] for r in own],
                    "subjects": [f"robot-{robot}"],
                }
            )

    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def credential_users(text: str) -> list[str]:
    """Usernames in a Zenoh usrpwd dictionary (``user:password`` per line), in file order.

    Blank lines are skipped; a line without ``:`` or with an empty user is a ValueError.
    """
    users: list[str] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        user, sep, _password = line.partition(":")
        if not sep or not user:
            raise ValueError(f"credentials line {number}: expected user:password")
        users.append(user)
    return users
