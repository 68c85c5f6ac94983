"""The ``[ros2]`` settings table: TOML, environment, validation with the field named."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from fleet.io.settings import Ros2Settings, load_settings

ROBOTS_PAGE = Path(__file__).resolve().parents[3] / "docs" / "robots.md"


def readme_sample() -> str:
    """The TurtleBot 4 settings file of docs/robots.md "Driving a ROS 2 robot"."""
    text = ROBOTS_PAGE.read_text()
    section = text[text.index("### A TurtleBot 4 on Jazzy with rmw_zenoh") :]
    return section[section.index("```toml\n") + 8 : section.index("```\n", 8)]


def test_defaults_are_a_jazzy_robot_with_odometry_on_the_agent_link() -> None:
    ros2 = load_settings().ros2
    assert ros2 == Ros2Settings()
    assert (ros2.key_mapping, ros2.distro, ros2.domain_id, ros2.namespace) == (
        "rmw_zenoh", "jazzy", 0, ""
    )  # fmt: skip
    assert (ros2.cmd_vel_topic, ros2.odom_topic, ros2.pose_source) == (
        "cmd_vel",
        "odom",
        "odometry",
    )
    assert ros2.connect == [] and ros2.origin == (0.0, 0.0, 0.0)


def test_the_readme_turtlebot4_sample_loads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(readme_sample())
    monkeypatch.setenv("PARKFLEET_ROS2__DOMAIN_ID", "7")
    settings = load_settings(path)
    assert settings.drive == "ros2" and settings.profile.max_speed == pytest.approx(0.306)
    ros2 = settings.ros2
    assert ros2.namespace == "/tb4_1" and ros2.cmd_vel_type.endswith("TwistStamped")
    assert ros2.domain_id == 7  # the environment beats the file
    assert ros2.connect == ["tcp/127.0.0.1:7447"] and ros2.origin == (2.0, -1.5, 1.5708)
    assert settings.connect == ["tls/fleet.yard.lan:7447"] and settings.fleet_name == "yard1"


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("cmd_vel_topic", "cmd vel"),
        ("cmd_vel_topic", "cmd_vel/"),
        ("odom_topic", "~/odom"),
        ("odom_topic", "1odom"),
        ("namespace", "tb4_1"),  # a namespace is absolute
        ("namespace", "/tb4_1/"),
        ("node_name", "parkfleet-1"),
        ("domain_id", 233),
        ("key_mapping", "dds"),
        ("distro", "foxy"),
        ("origin", [0.0, float("nan"), 0.0]),
        ("odom_frame_id", "odom frame"),
        ("oops", 1),
    ],
)
def test_bad_values_are_refused_with_the_field_name(field: str, value: object) -> None:
    with pytest.raises(ValidationError, match=field):
        load_settings(ros2={field: value})


def test_the_turtlebot4_bridge_example_loads() -> None:
    path = Path(__file__).parents[3] / "docs/examples/turtlebot4-create3-bridge.toml"
    ros2 = load_settings(path).ros2
    assert ros2.key_mapping == "bridge" and ros2.pose_source == "localiser"
    assert ros2.odom_jump_m == 0.25 and ros2.clock_step_s == 1.0
