"""``parkfleet agent`` drive loading."""

from __future__ import annotations

import pytest

from fleet.settings import load_settings
from robot_agent.cli import load_drive, parse_pose
from sim_agent.drive import SimDrive


def test_without_drive_the_error_explains_how_to_plug_one_in() -> None:
    with pytest.raises(ValueError, match="make_drive"):
        load_drive(None, load_settings(), (0, 0, 0))


def test_sim_alias_and_import_path() -> None:
    drive = load_drive("sim", load_settings(), (1.0, 2.0, 0.5))
    assert isinstance(drive, SimDrive) and drive.true_pose == (1.0, 2.0, 0.5)
    with pytest.raises(ValueError, match="missing"):
        load_drive("builtins:str", load_settings(), (0, 0, 0))
    with pytest.raises(ValueError, match="module:factory"):
        load_drive("nocolon", load_settings(), (0, 0, 0))


def test_parse_pose() -> None:
    assert parse_pose("1,2") == (1.0, 2.0, 0.0)
    assert parse_pose("1,-2,3.5") == (1.0, -2.0, 3.5)
