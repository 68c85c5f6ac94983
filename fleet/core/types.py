"""Type names shared across parkfleet (one definition each).

Frames and units: postures are ``(x [m], y [m], theta [rad])`` in the world frame,
theta counter-clockwise from the x axis.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

#: Law names on every interface: ``ccw`` = Eq. (17) (omega >= 0), ``cw`` = Eq. (20) (omega <= 0).
Law = Literal["ccw", "cw"]
LAWS: tuple[Law, Law] = ("ccw", "cw")

#: A planar posture (x [m], y [m], theta [rad]) in the world frame.
Posture = tuple[float, float, float]
#: Controller gains (kx [1/s], ky, ktheta) of laws (17)/(20).
GainTriple = tuple[float, float, float]

__all__ = ["LAWS", "BoolArray", "FloatArray", "GainTriple", "IntArray", "Law", "Posture"]
