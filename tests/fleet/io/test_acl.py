"""The fleet access-control list (pure): shape, per-robot grants, rejected ids."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import zenoh
from pydantic import ValidationError

from fleet.core.wire import Keys
from fleet.io.acl import ALL_MESSAGES, credential_users, fleet_acl, ros2_keys
from fleet.io.settings import load_settings
from fleet.io.transport import zenoh_config

KEYS = Keys("yard1")


def grants(acl: dict[str, Any], subject: str) -> set[tuple[str, str, str]]:
    """(flow, message, key) triples a subject is allowed."""
    rules = {r["id"]: r for r in acl["rules"]}
    out: set[tuple[str, str, str]] = set()
    for policy in acl["policies"]:
        if subject in policy["subjects"]:
            for rid in policy["rules"]:
                rule = rules[rid]
                assert rule["permission"] == "allow"
                out |= {
                    (f, m, k)
                    for f in rule["flows"]
                    for m in rule["messages"]
                    for k in rule["key_exprs"]
                }
    return out


def test_default_deny_robots_publish_only_their_own_keys() -> None:
    acl = fleet_acl(KEYS, ["r1", "r2"])
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    r1 = grants(acl, "robot-r1")
    published = {(m, k) for f, m, k in r1 if f == "ingress" and m in ("put", "delete")}
    assert published == {
        ("put", "parkfleet/yard1/robot/r1/state"),
        ("put", "parkfleet/yard1/cell/*/*/r1"),  # its peer stream, in whatever cell
        ("put", "parkfleet/yard1/robot/r1/description"),
    }
    tokens = {k for f, m, k in r1 if f == "ingress" and m == "liveliness_token"}
    assert tokens == {"parkfleet/yard1/alive/r1"}
    delivered = {k for f, m, k in r1 if f == "egress" and m == "put"}
    assert "parkfleet/yard1/robot/r1/assignment" in delivered
    assert "parkfleet/yard1/robot/r2/assignment" not in delivered
    assert not any("assignment" in k for f, m, k in r1 if f == "ingress" and m == "put")


def test_only_service_identities_may_send_assignments() -> None:
    acl = fleet_acl(KEYS, ["r1"], service_identities=["fleet", "router-b"])
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["service"]["usernames"] == ["fleet", "router-b"]
    assert ("ingress", "put", "**") in grants(acl, "service")
    assert set(ALL_MESSAGES) == {m for _, m, _ in grants(acl, "service")}


def test_identity_can_be_the_certificate_common_name() -> None:
    acl = fleet_acl(KEYS, ["r1"], identity="cert_common_name")
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["robot-r1"] == {"id": "robot-r1", "cert_common_names": ["r1"]}


@pytest.mark.parametrize("bad", ["r*", "**", "r/1", "r$", "", "_service"])
def test_robot_ids_with_wildcards_are_rejected(bad: str) -> None:
    with pytest.raises(ValueError, match="invalid"):
        fleet_acl(KEYS, [bad])


def test_duplicate_or_overlapping_ids_are_rejected() -> None:
    with pytest.raises(ValueError, match="duplicate"):
        fleet_acl(KEYS, ["r1", "r1"])
    with pytest.raises(ValueError, match="both robot and service"):
        fleet_acl(KEYS, ["fleet"])


def test_credential_users_reads_the_usrpwd_dictionary() -> None:
    assert credential_users("fleet:a:b\n\nr1:x\n") == ["fleet", "r1"]
    with pytest.raises(ValueError, match="line 2"):
        credential_users("r1:x\nnocolon\n")


def test_settings_reject_wildcard_acl_ids_and_unpaired_secrets() -> None:
    with pytest.raises(ValidationError, match="acl_robot_ids"):
        load_settings(acl_robot_ids=["r*"])
    with pytest.raises(ValidationError, match="together"):
        load_settings(zenoh_user="r1")
    with pytest.raises(ValidationError, match="together"):
        load_settings(tls_cert=Path("c.pem"))


def test_zenoh_config_carries_usrpwd_tls_and_the_generated_acl(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    users = tmp_path / "users.txt"
    users.write_text("fleet:pw0\nr1:pw1\nr2:pw2\n")
    monkeypatch.setenv("PARKFLEET_ACL", "true")
    monkeypatch.setenv("PARKFLEET_ZENOH_CREDENTIALS_FILE", str(users))
    settings = load_settings(
        listen=["tls/0.0.0.0:7447"],
        tls_root_ca=tmp_path / "ca.pem",
        tls_cert=tmp_path / "host.pem",
        tls_key=tmp_path / "host.key",
        fleet_name="yard1",
    )
    conf = json.loads(str(zenoh_config(settings, "router")))
    assert conf["transport"]["auth"]["usrpwd"]["dictionary_file"] == str(users)
    tls = conf["transport"]["link"]["tls"]
    assert tls["enable_mtls"] is True and tls["root_ca_certificate"] == str(tmp_path / "ca.pem")
    acl = conf["access_control"]
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    robots = {s["id"] for s in acl["subjects"]} - {"service"}
    assert robots == {"robot-r1", "robot-r2"}  # every user but the service users
    client = json.loads(str(zenoh_config(settings, "client")))
    assert client["access_control"]["enabled"] is False  # robots may share the settings file


def test_a_credentials_file_with_a_wildcard_user_is_rejected(tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("fleet:pw0\nr*:pw1\n")
    settings = load_settings(acl=True, zenoh_credentials_file=users)
    with pytest.raises(ValueError, match="invalid robot id 'r\\*'"):
        zenoh_config(settings, "router")


def test_acl_file_is_used_verbatim(tmp_path: Path) -> None:
    block = tmp_path / "acl.json5"
    block.write_text(
        '{ enabled: true, default_permission: "allow", rules: [], subjects: [], policies: [] }'
    )
    conf = json.loads(str(zenoh_config(load_settings(acl_file=block), "router")))
    assert conf["access_control"]["default_permission"] == "allow"


def test_a_broken_acl_file_is_a_clear_error(tmp_path: Path) -> None:
    block = tmp_path / "acl.json5"
    block.write_text("{ enabled: true, default_permission: ")
    with pytest.raises(ValueError, match="invalid access_control"):
        zenoh_config(load_settings(acl_file=block), "router")


def test_robots_hear_operator_commands_but_only_services_and_operators_send_them() -> None:
    acl = fleet_acl(KEYS, ["r1", "r2"], operator_identities=["ops"])
    fleet_key, own_key = KEYS.control(), KEYS.control("r1")
    r1 = grants(acl, "robot-r1")
    assert {("ingress", "declare_subscriber", k) for k in (fleet_key, own_key)} <= r1
    assert {("egress", "put", k) for k in (fleet_key, own_key)} <= r1
    assert ("egress", "put", KEYS.control("r2")) not in r1  # not another robot's commands
    assert not any("control" in k for f, m, k in r1 if f == "ingress" and m == "put")
    ops = grants(acl, "operator")
    assert {k for f, m, k in ops if f == "ingress" and m == "put"} == {
        fleet_key,
        KEYS.all_robot_controls,
    }
    assert ("ingress", "liveliness_query", KEYS.all_alive) in ops
    assert not any(m == "liveliness_token" for f, m, k in ops if f == "ingress")
    with pytest.raises(ValueError, match="both robot and operator"):
        fleet_acl(KEYS, ["r1"], operator_identities=["r1"])
    with pytest.raises(ValueError, match="both service and operator"):
        fleet_acl(KEYS, ["r1"], operator_identities=["fleet"])


def test_a_robot_answers_queries_on_its_own_description_only() -> None:
    r1 = grants(fleet_acl(KEYS, ["r1", "r2"]), "robot-r1")
    own = KEYS.description("r1")
    assert {("ingress", "declare_queryable", own), ("ingress", "reply", own)} <= r1
    assert ("egress", "query", own) in r1
    assert not any(k == KEYS.description("r2") for _, _, k in r1)


def test_ros2_grants_cover_exactly_the_robots_namespace() -> None:
    """The rmw_zenoh keys and graph tokens the ROS 2 drive uses (robot_agent.drives.ros2_names)
    fall under the grant for its namespace (and those below), another namespace's do not."""
    from robot_agent.drives.ros2_names import data_key, endpoint_token, node_token, topic_path

    acl = fleet_acl(KEYS, ["r1", "r2"], ros2_namespaces={"r1": "/tb4_1"}, ros2_domain_id=3)
    r1 = grants(acl, "robot-r1")
    granted = [zenoh.KeyExpr(k) for f, m, k in r1 if f == "ingress" and m == "put"]

    def allowed(key: str) -> bool:
        return any(g.includes(zenoh.KeyExpr(key)) for g in granted)

    def keys_of(namespace: str) -> list[str]:
        path = topic_path("rmw_zenoh", "cmd_vel", namespace)
        token_fields = dict(
            domain_id=3, zid="aa", node_id=0, namespace=namespace, node_name="parkfleet_r1",
            topic=f"{namespace}/cmd_vel", ros_type="geometry_msgs/msg/Twist", type_hash="H",
            qos="::,:,:,:,,",
        )  # fmt: skip
        return [
            data_key("rmw_zenoh", 3, path, "geometry_msgs/msg/Twist", "H"),
            node_token(3, "aa", 0, namespace, "parkfleet_r1"),
            endpoint_token("MP", entity_id=1, **token_fields),  # type: ignore[arg-type]
            topic_path("bridge", "cmd_vel", namespace),
        ]

    assert all(allowed(k) for k in keys_of("/tb4_1"))
    assert not any(allowed(k) for k in keys_of("/tb4_2"))
    assert all(allowed(k) for k in keys_of("/tb4_1/arm"))  # namespaces below are the robot's
    assert not any(allowed(k) for k in keys_of("/tb4_10"))
    assert not any("tb4" in k for _, _, k in grants(acl, "robot-r2"))


@pytest.mark.parametrize(
    ("namespace", "why"),
    [
        ("", "root"),
        ("/", "root"),
        ("/0", "invalid"),  # bridge keys 0/** would be every rmw_zenoh key of domain 0
        ("/tb*", "invalid"),
        ("/a/**", "invalid"),
        ("/parkfleet", "fleet's own keys"),  # bridge keys parkfleet/** = the whole fleet
    ],
)
def test_ros2_namespaces_that_would_grant_more_than_a_robot_are_refused(
    namespace: str, why: str
) -> None:
    with pytest.raises(ValueError, match=why):
        ros2_keys(namespace, 0)


def test_ros2_namespaces_must_name_robots_and_be_their_own() -> None:
    with pytest.raises(ValueError, match="not robots"):
        fleet_acl(KEYS, ["r1"], ros2_namespaces={"r9": "/tb4_9"})
    with pytest.raises(ValueError, match="share a ROS 2 namespace"):
        fleet_acl(KEYS, ["r1", "r2"], ros2_namespaces={"r1": "/tb", "r2": "/tb/"})
