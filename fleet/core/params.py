"""Validated parameter models shared by the simulator, the agents and the service."""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]


class Gains(BaseModel):
    """Controller gains (kx [1/s], ky, ktheta) of laws (17)/(20); all strictly positive."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kx: PositiveFloat
    ky: PositiveFloat
    ktheta: PositiveFloat

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.kx, self.ky, self.ktheta)


class Tolerance(BaseModel):
    """Arrival tolerance: position [m] and heading [rad] (strict inequalities)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    position: PositiveFloat = 0.05
    heading: PositiveFloat = 0.02


class RobotProfile(BaseModel):
    """Physical profile of a differential-drive robot (Eq. 2 and Table 10 of the paper).

    ``max_wheel_speed`` [rad/s] may be ``inf`` for an unlimited (paper) robot.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    wheel_radius: PositiveFloat = 0.05
    half_axle: PositiveFloat = 0.135
    max_wheel_speed: Annotated[float, Field(gt=0.0)] = 20.0
    radius: PositiveFloat = 0.2

    @property
    def max_speed(self) -> float:
        """Top forward speed [m/s] with both wheels at the limit."""
        return self.wheel_radius * self.max_wheel_speed


class Avoidance(BaseModel):
    """Obstacle repulsion of Eq. (27): K_avoid [m^2/s], influence radii [m], x_OA guard [m]."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    k_avoid: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 4.0
    peer_radius: PositiveFloat = 1.0
    min_x_oa: PositiveFloat = 0.05


DEFAULT_TOLERANCE = Tolerance()
"""The paper's tight tolerance (comparative cases I and II): 0.05 m, 0.02 rad."""

UNLIMITED = RobotProfile(max_wheel_speed=math.inf)
"""Robot with no wheel-speed limit, as in the paper's simulations."""
