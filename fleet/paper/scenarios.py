"""The paper's simulation scenarios and experiment, with its gains and tolerances.

Sources in ``shared/paper.txt``: first scenario (Section 4, Table 1), comparative cases
I, II, III (Tables 4, 6, 8) and the parallel-parking experiment (Section 5, Tables 10-11).
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict

from fleet.core.params import UNLIMITED, Gains, RobotProfile, Tolerance
from fleet.core.types import Law, Posture

CaseName = Literal["first", "I", "II", "III", "parking"]
CASES: tuple[CaseName, ...] = ("first", "I", "II", "III", "parking")


class Scenario(BaseModel):
    """One posture-stabilisation run of the paper: start, goal, gains per law, tolerance."""

    model_config = ConfigDict(frozen=True)

    name: CaseName
    title: str
    start: Posture
    goal: Posture
    gains: dict[Law, Gains]
    tolerance: Tolerance
    profile: RobotProfile = UNLIMITED


_TIGHT = Tolerance(position=0.05, heading=0.02)  # comparative cases I and II
_LOOSE = Tolerance(position=0.1, heading=0.1)  # comparative case III

SCENARIOS: dict[CaseName, Scenario] = {
    "first": Scenario(
        name="first",
        title="First scenario (Table 1)",
        start=(0.0, 4.0, math.pi / 2),
        goal=(5.0, -5.0, -math.pi / 2),
        gains={"ccw": Gains(kx=2.6, ky=1.5, ktheta=1.5), "cw": Gains(kx=2.1, ky=1.25, ktheta=1.25)},
        tolerance=_TIGHT,
    ),
    "I": Scenario(
        name="I",
        title="Comparative case I (Table 4)",
        start=(0.0, 2.0, 0.0),
        goal=(2.0, -1.0, math.pi / 4),
        gains={"ccw": Gains(kx=3, ky=1.4, ktheta=13), "cw": Gains(kx=6.9, ky=25, ktheta=29)},
        tolerance=_TIGHT,
    ),
    "II": Scenario(
        name="II",
        title="Comparative case II (Table 6)",
        start=(4.0, 1.0, -0.2),
        goal=(0.0, 0.0, 0.0),
        gains={"ccw": Gains(kx=4, ky=1.4, ktheta=13), "cw": Gains(kx=3.5, ky=7, ktheta=5)},
        tolerance=_TIGHT,
    ),
    "III": Scenario(
        name="III",
        title="Comparative case III, parallel parking (Table 8)",
        start=(0.0, 2.0, 0.0),
        goal=(0.0, -2.0, 0.0),
        gains={"ccw": Gains(kx=0.6, ky=2.9, ktheta=2.4), "cw": Gains(kx=2, ky=6, ktheta=6)},
        tolerance=_LOOSE,
    ),
    "parking": Scenario(
        name="parking",
        title="Parallel-parking experiment (Tables 10, 11)",
        start=(0.0, -0.5, 0.0),
        goal=(0.0, 0.5, 0.0),
        gains={"ccw": Gains(kx=0.57, ky=1.8, ktheta=2.4), "cw": Gains(kx=0.3, ky=1.3, ktheta=1.55)},
        tolerance=_TIGHT,
        profile=RobotProfile(wheel_radius=0.05, half_axle=0.135, max_wheel_speed=math.inf),
    ),
}
