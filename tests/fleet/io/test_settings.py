"""Settings: defaults, PARKFLEET_ environment, TOML file, explicit overrides."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pydantic import ValidationError

from fleet.io.settings import DEFAULT_ROUTER_ENDPOINT, load_settings
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
