"""Site files (TOML and JSON): the example loads; every error names its line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet.io.settings import load_settings
from fleet.io.site_file import SiteFileError, json_lines, load_site, parse_site, toml_lines

EXAMPLE = Path(__file__).resolve().parents[3] / "fleet" / "io" / "sites" / "carpark.toml"

GOOD = """\
name = "t"
obstacles = [
    { x = 5.0, y = 5.0, radius = 1.0 },
    { x = -5.0, y = 5.0, radius = 1.0 },
]

[yard]
xmin = -10.0
xmax = 10.0
ymin = -10.0
ymax = 10.0

[[keep_out]]
name = "ramp"
rect = { xmin = -10.0, xmax = -8.0, ymin = -1.0, ymax = 1.0 }

[[bays]]
name = "A1"
pose = { x = 0.0, y = 6.0 }

[[bays]]
name = "C1"
group = "charging"
[bays.pose]
x = 3.0
y = 6.0
"""


def problems(text: str, suffix: str = ".toml", **radii: float) -> list[tuple[int, str]]:
    with pytest.raises(SiteFileError) as caught:
        parse_site(text, Path(f"site{suffix}"), **radii)
    return caught.value.problems


def test_the_shipped_car_park_loads_and_sets_the_yard() -> None:
    settings = load_settings(site_file=EXAMPLE)
    site = settings.site
    assert site is not None and settings.yard == site.yard.as_tuple()
    assert [b.name for b in site.group("charging")] == ["C1", "C2", "C3"]
    assert {z.name for z in site.keep_out} == {"ramp", "walkway", "hydrant"}
    assert len(site.obstacles) == 4
    assert [z.name for z in site.zones] == ["entrance"]
    assert [(lane.name, lane.one_way) for lane in site.lanes] == [
        ("main", False),
        ("north", False),
        ("south", False),
        ("in", True),
        ("out", True),
    ]


def test_a_lane_through_a_wall_fails_the_site_naming_its_line(tmp_path: Path) -> None:
    path = tmp_path / "site.toml"
    path.write_text(
        "[yard]\nxmin = -10.0\nxmax = 10.0\nymin = -10.0\nymax = 10.0\n"
        "[[walls]]\npoints = [[-2.0, 0.0], [2.0, 0.0]]\n"
        '[[lanes]]\nname = "cut"\npoints = [[0.0, -3.0], [0.0, 3.0]]\n'
    )
    with pytest.raises(SiteFileError) as failed:
        load_site(path, robot_radius=0.2, peer_radius=1.0)
    ((line, message),) = failed.value.problems
    assert line == 10 and "lane cut: the leg from point 0 to point 1 passes 0.00 m" in message


def test_a_valid_file_parses_in_both_formats() -> None:
    site = parse_site(GOOD, Path("s.toml"), robot_radius=0.2, peer_radius=1.0)
    as_json = json.dumps(site.model_dump(mode="json"), indent=2)
    assert parse_site(as_json, Path("s.json")) == site
    assert site.bay("C1") is not None and site.bay("C1").pose.x == 3.0  # type: ignore[union-attr]


def test_toml_lines_locate_keys_tables_array_elements() -> None:
    lines = toml_lines(GOOD)
    assert lines[("obstacles",)] == 2
    assert lines[("obstacles", 1)] == 4
    assert lines[("yard", "xmax")] == 9
    assert lines[("keep_out", 0, "rect")] == 15
    assert lines[("bays", 1)] == 21 and lines[("bays", 1, "pose", "y")] == 26


def test_json_lines_locate_every_value() -> None:
    text = (
        '{\n  "yard": {"xmin": 0,\n    "xmax": 1},\n  "bays": [\n    {"name": "A"},\n'
        '    {"name": "B"}\n  ]\n}'
    )
    lines = json_lines(text)
    assert lines[("yard", "xmax")] == 3 and lines[("bays", 1, "name")] == 6


def test_validation_errors_name_the_line_and_the_field() -> None:
    bad = GOOD.replace("y = 6.0 }", "y = 66.0 }").replace('name = "ramp"', 'name = "r a m p"')
    found = problems(bad)
    assert (14, "keep_out[0].name: String should match pattern "
            "'^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$'") in found  # fmt: skip
    bad = GOOD.replace("x = 3.0\n", 'x = "east"\n')
    assert problems(bad) == [(25, "bays[1].pose.x: Input should be a valid number, unable to "
                                  "parse string as a number")]  # fmt: skip


def test_consistency_errors_name_the_line_of_the_culprit() -> None:
    dup = GOOD.replace('name = "C1"', 'name = "A1"')
    assert problems(dup) == [(22, "bays[1].name: two bays are named 'A1'")]
    outside = GOOD.replace("pose = { x = 0.0, y = 6.0 }", "pose = { x = 0.0, y = 16.0 }")
    assert problems(outside) == [(19, "bays[0].pose: bay A1 at (0, 16) is outside the yard")]
    close = GOOD.replace("x = 3.0\n", "x = 0.5\n")
    assert problems(close, robot_radius=0.2, peer_radius=1.0) == [
        (24, "bays[1].pose: bays A1 and C1 are 0.50 m apart: bays must be more than the peer "
             "influence radius 1 m apart")
    ]  # fmt: skip


def test_syntax_errors_name_the_line() -> None:
    assert problems('name = "t"\n[yard\nxmin = 1\n')[0][0] == 2
    assert problems('{\n  "yard": {\n    "xmin": 0,,\n  }\n}', ".json")[0][0] == 3


def test_settings_refuse_two_different_yards_and_missing_files(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="set one of them"):
        load_settings(site_file=EXAMPLE, yard=(-1.0, 1.0, -1.0, 1.0))
    with pytest.raises(FileNotFoundError, match="site file not found"):
        load_site(tmp_path / "nope.toml")
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (5 * 1024 * 1024))
    with pytest.raises(SiteFileError, match="larger than"):
        load_site(big)


def test_a_wall_that_crosses_itself_names_its_line_and_field() -> None:
    walls = GOOD + (
        '\n[[walls]]\nname = "north"\npoints = [[-9.0, 9.0], [9.0, 9.0]]\n'
        '\n[[walls]]\nname = "bow"\nclosed = true\npoints = [[0, 0], [2, 2], [2, 0], [0, 2]]\n'
    )
    ((line, message),) = problems(walls)
    assert line == 32 and message.startswith("walls[1]: Value error, points: the wall crosses")
    good = parse_site(walls.replace("[2, 2], [2, 0]", "[2, 0], [2, 2]"), Path("site.toml"))
    assert [w.name for w in good.walls] == ["north", "bow"] and len(good.static_obstacles()) == 7


def test_a_bay_that_walls_close_off_fails_loading_with_its_name_and_line() -> None:
    room = GOOD + (
        '\n[[walls]]\nname = "room"\nclosed = true\n'
        "points = [[1.5, 4.5], [4.5, 4.5], [4.5, 7.5], [1.5, 7.5]]\n"
    )
    assert problems(room, robot_radius=0.2, peer_radius=1.0) == [
        (24, "bays[1].pose: bay C1: no route reaches it from bay A1 (walls close it off from "
             "the other bays for a robot of radius 0.2 m)")
    ]  # fmt: skip
    door = room.replace(
        "closed = true\npoints = [[1.5, 4.5], [4.5, 4.5], [4.5, 7.5], [1.5, 7.5]]",
        "points = [[3.0, 4.5], [4.5, 4.5], [4.5, 7.5], [1.5, 7.5], [1.5, 4.5]]",
    )  # the same room with a door on its south side
    assert parse_site(door, Path("site.toml"), robot_radius=0.2, peer_radius=1.0).walls
