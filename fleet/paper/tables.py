"""What the paper publishes about its comparisons: the VFO and FT rows of Tables 5, 7, 9
and the comparative sentences of Section 4 that rest on them.

The rows for the paper's own laws (17) and (20) are held out of ``shared/paper.txt``; the
reproduction (:mod:`fleet.paper.reproduce`) is checked against them independently.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from fleet.paper.scenarios import CaseName


class PaperRow(BaseModel):
    """One published row: Eq. (25) effort, travelled distance [m], time [s]."""

    model_config = ConfigDict(frozen=True)

    control_effort: float
    distance: float
    time: float


#: Tables 5 (case I), 7 (case II) and 9 (case III).
PAPER_ROWS: dict[tuple[CaseName, str], PaperRow] = {
    ("I", "VFO"): PaperRow(control_effort=7.7404, distance=4.083, time=1.68),
    ("I", "FT"): PaperRow(control_effort=8.5589, distance=5.0882, time=3.81),
    ("II", "VFO"): PaperRow(control_effort=14.5271, distance=6.5393, time=3.23),
    ("II", "FT"): PaperRow(control_effort=12.8195, distance=12.1738, time=4.06),
    ("III", "VFO"): PaperRow(control_effort=13.8588, distance=7.6685, time=1.68),
    ("III", "FT"): PaperRow(control_effort=19.4322, distance=18.0394, time=3.37),
}

#: Targets of the baselines against the published rows (the brief): relative on effort
#: and distance, absolute [s] on time.
RELATIVE_TOLERANCE = 0.02
TIME_TOLERANCE = 0.02
