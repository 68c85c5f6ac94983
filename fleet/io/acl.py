"""Zenoh access control for a fleet: who may publish, subscribe and query which keys.

Pure module (no Zenoh import, no file access): :func:`fleet_acl` builds the
``access_control`` block of a router's Zenoh config from the fleet's key layout
(:class:`fleet.core.wire.Keys`), the robot ids and the trusted service identities.

The policy is *default deny*. A connecting session is recognised by its usrpwd username
or by the common name of its TLS client certificate (``identity``):

* a **robot** ``<id>`` (identity equal to its robot id) may publish only its own state
  ``robot/<id>/state`` and description ``robot/<id>/description`` (put, and a queryable
  answering queries on it), and declare only its own liveliness token ``alive/<id>``; it may
  subscribe to every robot's state, to the obstacles, to its own assignments and to the
  operator control keys (the fleet's ``control`` and its own ``robot/<id>/control``), query
  the obstacles, watch the ``alive/*`` tokens and send its link check's echo query to the
  router's admin space (``@/<router zid>/router``, replies only). The router forwards to it
  only peers' states, the obstacles, its *own* assignments and the operator commands
  meant for it: operator commands reach every robot, but only a service identity may
  publish them, so a robot's forged e-stop release is dropped at the router's ingress;
* optionally, a robot's **ROS 2 traffic** (``ros2_namespaces``: robot id -> its ROS
  namespace): everything under that namespace, both ways -- the rmw_zenoh data keys
  ``<domain>/<namespace>/**``, its ROS-graph liveliness tokens
  ``@ros2_lv/<domain>/<zid>/<node>/<entity>/<kind>/<enclave>/<namespace>/**`` (and of the
  namespaces below it: rmw_zenoh's watch on the domain's tokens is allowed, and answered
  with this namespace's only) and the
  zenoh-bridge-ros2dds keys ``<namespace>/**``. This is what the "robot's router pointed at
  the fleet host" set-up needs: the robot's rmw_zenoh router and the agent's ROS 2 drive
  connect with the robot's identity. A robot never gets another namespace's ROS keys;
* an **operator** identity (``parkfleet estop | pause | resume`` on an operator's
  machine) may publish operator commands on the fleet's and every robot's control key,
  watch every robot's state and query the ``alive/*`` tokens (to confirm) -- and nothing
  else: it cannot assign, forge a state or declare a token;
* a **service** identity (the fleet service when it runs apart from the router, other
  routers of a mesh) may do everything: only services and operators send operator
  commands, only services assignments;
* anyone else is refused everything (and, with usrpwd, cannot connect at all).

The rules apply where the router sees the message: a ``put`` on another robot's state or
on any assignment or control key from a robot is dropped at the router's ingress.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
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


#: Prefix of rmw_zenoh's ROS-graph liveliness tokens (``robot_agent.drives.ros2_names``).
ROS_GRAPH_PREFIX = "@ros2_lv"
#: One part of a ROS name (ROS 2 name rules); the fleet's keys all start with this prefix.
_ROS_NAME_PART = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
FLEET_KEY_PREFIX = "parkfleet"
#: The link check's echo query (``robot_agent.link``): a router's own admin-space entry.
ROUTER_ECHO = "@/*/router"


def ros2_keys(namespace: str, domain_id: int) -> list[str]:
    """Key expressions of every ROS 2 message and graph token under ``namespace`` on
    ``domain_id``, for both key mappings (module docstring).

    Raises ValueError for the root namespace (it would grant the whole ROS domain), a name
    that is not a ROS namespace (each part a letter or ``_`` then letters, digits, ``_``:
    so no wildcard and never a domain number), or one whose bridge keys would cover the
    fleet's own (``parkfleet/**``).
    """
    chunks = namespace.strip("/")
    if not chunks:
        raise ValueError("a robot's ROS 2 namespace in the access-control list cannot be the root")
    if not all(_ROS_NAME_PART.fullmatch(part) for part in chunks.split("/")):
        raise ValueError(f"invalid ROS 2 namespace {namespace!r} in the access-control list")
    if chunks.split("/")[0] == FLEET_KEY_PREFIX:
        raise ValueError(
            f"ROS 2 namespace {namespace!r}: its bridge keys would cover the fleet's own keys"
        )
    mangled = "%" + chunks.replace("/", "%")  # rmw_zenoh writes each / of a name as %
    graph = f"{ROS_GRAPH_PREFIX}/{domain_id}/*/*/*/*/*"
    return [
        f"{domain_id}/{chunks}/**",
        f"{graph}/{mangled}/**",
        f"{graph}/{mangled}%$*/**",  # nodes in namespaces below it (``%tb4_1%arm``)
        f"{chunks}/**",
    ]


def fleet_acl(
    keys: Keys,
    robot_ids: Iterable[str],
    *,
    service_identities: Iterable[str] = ("fleet",),
    operator_identities: Iterable[str] = (),
    identity: Identity = "username",
    ros2_namespaces: Mapping[str, str] | None = None,
    ros2_domain_id: int = 0,
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
        Identities granted everything (fleet service, meshed routers).
    operator_identities
        Identities that may send operator commands and watch states (module docstring).
    identity
        What a subject matches: ``username`` (``transport/auth/usrpwd``) or
        ``cert_common_name`` (mutual TLS client certificate).
    ros2_namespaces, ros2_domain_id
        Robot id -> ROS 2 namespace (e.g. ``/tb4_1``) of robots whose ROS 2 traffic goes
        through this router, on ROS domain ``ros2_domain_id`` (module docstring).

    Raises
    ------
    ValueError
        On an invalid or duplicate id, an id that is both a robot and a service, a ROS 2
        namespace for an id that is not a robot, or a root or shared ROS 2 namespace.
    """
    robots = [validate_id(r) for r in robot_ids]
    services = [validate_id(s, "service identity") for s in service_identities]
    operators = [validate_id(s, "operator identity") for s in operator_identities]
    if len(set(robots)) != len(robots):
        raise ValueError("duplicate robot id in the access-control list")
    for first, second, names in (
        ("robot", "service", set(robots) & set(services)),
        ("robot", "operator", set(robots) & set(operators)),
        ("service", "operator", set(services) & set(operators)),
    ):
        if names:
            raise ValueError(
                f"ids both {first} and {second} in the access-control list: {sorted(names)}"
            )
    field = _SUBJECT_FIELD[identity]
    namespaces = dict(ros2_namespaces or {})
    strangers = sorted(set(namespaces) - set(robots))
    if strangers:
        raise ValueError(f"ROS 2 namespaces for ids that are not robots of the ACL: {strangers}")
    ros_keys = {robot: ros2_keys(ns, ros2_domain_id) for robot, ns in namespaces.items()}
    if len({keys_[0] for keys_ in ros_keys.values()}) != len(ros_keys):
        raise ValueError("two robots share a ROS 2 namespace in the access-control list")

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

    if operators:
        commands = [keys.control(), keys.all_robot_controls]
        operator_rules = [
            _rule("operators-command", "ingress", ["put"], commands),
            _rule("operators-watch", "ingress", ["declare_subscriber"], [keys.all_states]),
            _rule(
                "operators-ask-alive",
                "ingress",
                ["liveliness_query", "declare_liveliness_subscriber"],
                [keys.all_alive],
            ),
            _rule("operators-states", "egress", ["put"], [keys.all_states]),
            _rule("operators-alive", "egress", ["reply", "liveliness_token"], [keys.all_alive]),
            _rule(
                "operators-declarations",
                "egress",
                ["declare_subscriber", "declare_queryable"],
                [f"{keys.root}/**"],
            ),
        ]
        rules += operator_rules
        subjects.append({"id": "operator", field: operators})
        policies.append(
            {
                "id": "operator",
                "rules": [r["id"] for r in operator_rules],
                "subjects": ["operator"],
            }
        )

    if robots:
        shared = [
            # What every robot may ask for ...
            _rule(
                "robots-subscribe",
                "ingress",
                ["declare_subscriber"],
                [keys.all_states, keys.all_peer_states, keys.obstacles, keys.control()],
            ),
            # the obstacles, the router's echo, and the silent robots of a cell it enters
            _rule(
                "robots-query",
                "ingress",
                ["query"],
                [keys.obstacles, keys.all_peer_states, ROUTER_ECHO],
            ),
            _rule(
                "robots-watch-alive",
                "ingress",
                ["declare_liveliness_subscriber", "liveliness_query"],
                [keys.all_alive],
            ),
            # ... and what the router may forward to it.
            _rule(
                "robots-receive",
                "egress",
                ["put"],
                [keys.all_states, keys.all_peer_states, keys.obstacles, keys.control()],
            ),
            _rule(
                "robots-replies",
                "egress",
                ["reply"],
                [keys.obstacles, keys.all_peer_states, keys.all_alive, ROUTER_ECHO],
            ),
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
                _rule(
                    f"robot-{robot}-publish",
                    "ingress",
                    ["put"],
                    # its fleet-rate state, its peer stream in any cell, its description
                    [keys.state(robot), f"{keys.root}/cell/*/*/{robot}", keys.description(robot)],
                ),
                _rule(
                    f"robot-{robot}-describe",
                    "ingress",
                    ["declare_queryable", "reply"],
                    [keys.description(robot)],
                ),
                _rule(f"robot-{robot}-asked", "egress", ["query"], [keys.description(robot)]),
                _rule(f"robot-{robot}-token", "ingress", ["liveliness_token"], [keys.alive(robot)]),
                _rule(
                    f"robot-{robot}-orders",
                    "ingress",
                    ["declare_subscriber"],
                    [keys.assignment(robot), keys.control(robot)],
                ),
                _rule(
                    f"robot-{robot}-receive",
                    "egress",
                    ["put"],
                    [keys.assignment(robot), keys.control(robot)],
                ),
            ]
            if robot in ros_keys:
                own += [
                    _rule(f"robot-{robot}-ros2-in", "ingress", ALL_MESSAGES, ros_keys[robot]),
                    _rule(f"robot-{robot}-ros2-out", "egress", ALL_MESSAGES, ros_keys[robot]),
                    # rmw_zenoh builds its graph from a watch on the whole domain's tokens;
                    # the router forwards it only this namespace's (the egress rule above).
                    _rule(
                        f"robot-{robot}-ros2-graph",
                        "ingress",
                        ["declare_liveliness_subscriber", "liveliness_query"],
                        [f"{ROS_GRAPH_PREFIX}/{ros2_domain_id}/**"],
                    ),
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
