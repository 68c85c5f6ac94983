"""The names each package exports: changing them is a deliberate API change, made here."""

from __future__ import annotations

import importlib

import pytest

EXPORTS = {
    "fleet.cli": ["main"],
    "fleet.service": ["FleetService"],
    "fleet.core.types": [
        "LAWS",
        "BoolArray",
        "FloatArray",
        "GainTriple",
        "IntArray",
        "Law",
        "Posture",
    ],
    "fleet.core.planner": [
        "Action",
        "Plan",
        "PlannerConfig",
        "PlanningSnapshot",
        "RobotSnapshot",
        "TaskDecision",
        "TaskSnapshot",
        "corridor_distance",
        "left_corridor",
        "plan",
    ],
    "robot_agent": ["Drive", "PoseReading", "RobotAgent"],
    "sim_agent": ["SimDrive", "SimFleet", "Spawn", "make_drive", "spawn_layout"],
    "api": [],
    "fleet.core": [],
    "fleet.paper": [],
    "fleet.io": [],
    "fleet.bench": [],
}


@pytest.mark.parametrize("module", sorted(EXPORTS))
def test_exported_names_are_locked_and_exist(module: str) -> None:
    mod = importlib.import_module(module)
    assert sorted(mod.__all__) == sorted(EXPORTS[module])
    for name in mod.__all__:
        assert hasattr(mod, name), f"{module}.__all__ names {name}, which it lacks"


@pytest.mark.parametrize("module", sorted(EXPORTS))
def test_every_package_documents_its_parts(module: str) -> None:
    doc = importlib.import_module(module).__doc__
    assert doc is not None and len(doc.strip().splitlines()) >= 2
