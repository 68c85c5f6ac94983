"""The benchmark's simulated robots, built from one seed: drives and the link between them.

One recipe for every policy of a benchmark run: :class:`SimFleet` (parkfleet's agents) and
the navground peers (:mod:`fleet.bench.peers`, which gets a :class:`SimRobots` from the
CLI) build their robots here, so robot k of a run has the same wheel bias and draws from the
same stream whatever drives it. Every drive is a :class:`~sim_agent.drive.SimDrive` (the
compiled step's Euler update, ``fleet.core.step.integrate_wheels``), wrapped in a
:class:`~sim_agent.disturbances.DisturbedDrive` when disturbances are on; the peers' states
go through a :class:`~sim_agent.disturbances.DelayedLink` when the link is disturbed.

Seeding: ``rng = default_rng(seed)``; robot k's drive draws from
``default_rng(rng.integers(2**63))`` taken in robot order, then the link from one more such
draw.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fleet.core.params import RobotProfile
from robot_agent.clock import SteppedClock
from sim_agent.disturbances import (
    REALISTIC,
    REALISTIC_LINK,
    DelayedLink,
    Disturbances,
    DisturbedDrive,
    LinkDisturbances,
)
from sim_agent.drive import SimDrive


@dataclass
class RobotSet:
    """Built robots: their clock (simulated [s]), drives in robot order, and the link
    (``None``: peers see each other's states at once)."""

    clock: SteppedClock
    drives: list[SimDrive | DisturbedDrive]
    link: DelayedLink[Any] | None


@dataclass(frozen=True)
class SimRobots:
    """How simulated robots are built (picklable, so a bench worker process can use it).

    ``disturbances`` of every drive; ``link`` between robots; ``noise_std`` (x, y [m],
    theta [rad]) of an undisturbed drive's reported pose (``parkfleet sim --noise``).
    """

    disturbances: Disturbances = field(default_factory=Disturbances)
    link: LinkDisturbances = field(default_factory=LinkDisturbances)
    noise_std: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def realistic(cls) -> SimRobots:
        """``--disturbed``: :data:`REALISTIC` drives on a :data:`REALISTIC_LINK`."""
        return cls(REALISTIC, REALISTIC_LINK)

    @property
    def disturbed(self) -> bool:
        return self.disturbances.active or self.link.active

    def build(
        self,
        starts: Sequence[tuple[float, float, float]],
        profile: RobotProfile,
        seed: int | None,
        period: float,
        clock: SteppedClock | None = None,
    ) -> RobotSet:
        """Robots at ``starts`` (world frame [m, rad]) stepped every ``period`` [s] on
        ``clock`` (default a new :class:`SteppedClock` at 0)."""
        stepped = clock if clock is not None else SteppedClock()
        rng = np.random.default_rng(seed)
        drives: list[SimDrive | DisturbedDrive] = []
        for start in starts:
            drive_rng = np.random.default_rng(rng.integers(2**63))
            pose = (float(start[0]), float(start[1]), float(start[2]))
            if self.disturbances.active:
                drives.append(
                    DisturbedDrive(
                        pose, profile, stepped, self.disturbances, drive_rng, max_step=period
                    )
                )
            else:
                drives.append(
                    SimDrive(
                        pose,
                        profile,
                        stepped,
                        max_step=period,
                        noise_std=self.noise_std,
                        rng=drive_rng,
                    )
                )
        link_rng = np.random.default_rng(rng.integers(2**63))
        link: DelayedLink[Any] | None = (
            DelayedLink(len(drives), period, self.link, link_rng) if self.link.active else None
        )
        return RobotSet(stepped, drives, link)
