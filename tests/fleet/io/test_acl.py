"""The fleet access-control list (pure): shape, per-robot grants, rejected ids."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from pydantic import ValidationError

from fleet.core.wire import Keys
from fleet.io.acl import ALL_MESSAGES, credential_users, fleet_acl
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
    assert published == {("put", "parkfleet/yard1/robot/r1/state")}
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
