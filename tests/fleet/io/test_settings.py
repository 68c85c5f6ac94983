"""Settings: defaults, PARKFLEET_ environment, TOML file, explicit overrides."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pydantic import ValidationError

from fleet.io.settings import (
    DEFAULT_ROUTER_ENDPOINT,
    RobotSettings,
    Settings,
    ZenohSettings,
    load_robot_settings,
    load_settings,
)
from fleet.io.transport import zenoh_config


def test_defaults_are_loopback_router_and_50_hz() -> None:
    s = load_settings()
    assert s.api_host == "127.0.0.1" and s.control_rate_hz == 50.0 and s.listen == []
    assert DEFAULT_ROUTER_ENDPOINT == "tcp/127.0.0.1:7447"


def test_environment_toml_and_overrides_layer_in_that_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    toml = tmp_path / "parkfleet.toml"
    toml.write_text(
        'fleet_name = "from-file"\ncontrol_rate_hz = 20\n[profile]\nmax_wheel_speed = 12.5\n'
    )
    monkeypatch.setenv("PARKFLEET_CONTROL_RATE_HZ", "25")
    s = load_settings(toml)
    assert s.fleet_name == "from-file"
    assert s.control_rate_hz == 25  # environment beats the file
    assert s.profile.max_wheel_speed == 12.5
    assert load_settings(toml, control_rate_hz=40).control_rate_hz == 40  # flags beat both


def test_bad_values_are_rejected_with_the_field_name(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PARKFLEET_ROBOT_ID", "robot/*")
    with pytest.raises(ValidationError, match="robot_id"):
        load_settings()


def test_missing_config_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="config file not found"):
        load_settings(tmp_path / "nope.toml")


def test_zenoh_config_turns_multicast_off_and_uses_default_endpoints() -> None:
    client = json.loads(str(zenoh_config(load_settings(), "client")))
    assert client["mode"] == "client"
    assert client["connect"]["endpoints"] == [DEFAULT_ROUTER_ENDPOINT]
    assert client["scouting"]["multicast"]["enabled"] is False
    router = json.loads(str(zenoh_config(load_settings(listen=["tcp/127.0.0.1:0"]), "router")))
    assert router["mode"] == "router" and router["listen"]["endpoints"] == ["tcp/127.0.0.1:0"]
    assert router["transport"]["link"]["tx"]["lease"] == 1000


def test_a_robot_s_settings_have_no_host_fields() -> None:
    robot = set(RobotSettings.model_fields)
    host_only = set(Settings.model_fields) - robot
    assert not any(name.startswith(("api_", "acl")) for name in robot)
    assert {"api_port", "api_token", "data_dir", "acl", "task_timeout_s"} <= host_only
    assert {"robot_id", "profile", "ros2", "connect", "tls_cert"} <= robot
    assert set(ZenohSettings.model_fields) < robot  # every role joins the network


def test_one_settings_file_serves_the_host_and_its_robots(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = tmp_path / "fleet.toml"
    config.write_text(
        'fleet_name = "yard2"\napi_port = 9001\nacl = true\ncontrol_rate_hz = 25.0\n'
        'robot_id = "r7"\n[profile]\nmax_wheel_speed = 15.0\n'
    )
    robot = load_robot_settings(config)
    assert (robot.fleet_name, robot.robot_id, robot.control_rate_hz) == ("yard2", "r7", 25.0)
    assert robot.profile.max_wheel_speed == 15.0
    assert not hasattr(robot, "api_port") and not hasattr(robot, "acl")
    host = load_settings(config)
    assert (host.api_port, host.acl, host.control_rate_hz) == (9001, True, 25.0)
    monkeypatch.setenv("PARKFLEET_CONFIG", str(config))  # the file named in the environment
    assert RobotSettings().robot_id == "r7"


def test_a_key_no_role_knows_is_still_an_error_for_a_robot(tmp_path: Path) -> None:
    config = tmp_path / "typo.toml"
    config.write_text("control_rate_hx = 25.0\n")
    with pytest.raises(ValidationError, match="control_rate_hx"):
        load_robot_settings(config)


def test_a_link_timeout_longer_than_peers_wait_for_a_silent_robot_is_refused() -> None:
    # peers take a robot silent for peer_stale_s as stopped; it must have held by then
    with pytest.raises(ValidationError, match=r"link_timeout_s .* at most safety\.peer_stale_s"):
        load_settings(link_timeout_s=5.0)
    assert load_settings(link_timeout_s=5.0, safety={"peer_stale_s": 5.0}).link_timeout_s == 5.0
