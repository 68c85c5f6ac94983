"""Roles of a fleet service on a shared store (no database driver needed to import this):
leader or standby, the refusal a standby gives writes, and what ``/healthz`` shows."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol, runtime_checkable

from fleet.core.tasks import FleetError


class Role(StrEnum):
    LEADER = "leader"
    STANDBY = "standby"


class NotLeader(FleetError):
    """A write sent to a standby; ``address`` is the leader's API (None: no leader now)."""

    def __init__(self, address: str | None) -> None:
        where = f"the leader is {address}" if address else "no leader is elected yet"
        super().__init__(f"this fleet service is a standby: {where}")
        self.address = address


@dataclass(frozen=True)
class FailoverStatus:
    """This service's role, the current term and leader as it last saw them, its name."""

    role: Role
    term: int
    leader: str | None
    service: str


@runtime_checkable
class HasFailover(Protocol):
    """A service that leads or stands by (``fleet.service.standby.FailoverService``)."""

    def failover_status(self) -> FailoverStatus: ...
