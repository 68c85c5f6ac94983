"""``parkfleet agent`` drive loading."""

from __future__ import annotations

import pytest

from fleet.cli.agent import DRIVES, load_drive, parse_pose
from fleet.io.settings import load_settings
from sim_agent.drive import SimDrive


def test_without_drive_the_error_explains_how_to_plug_one_in() -> None:
    with pytest.raises(ValueError, match="make_drive"):
        load_drive(None, load_settings())


def test_sim_is_a_named_factory_like_any_other_drive() -> None:
    assert DRIVES["sim"] == "sim_agent.drive:make_drive"
    settings = load_settings(sim_start=(1.0, 2.0, 0.5))
    for spec in ("sim", "sim_agent.drive:make_drive"):
        drive = load_drive(spec, settings)
        assert isinstance(drive, SimDrive) and drive.true_pose == (1.0, 2.0, 0.5)


def test_bad_drive_specs_are_explained() -> None:
    with pytest.raises(ValueError, match="missing"):
        load_drive("builtins:str", load_settings())
    with pytest.raises(ValueError, match="module:factory"):
        load_drive("nocolon", load_settings())


def test_parse_pose() -> None:
    assert parse_pose("1,2") == (1.0, 2.0, 0.0)
    assert parse_pose("1,-2,3.5") == (1.0, -2.0, 3.5)
