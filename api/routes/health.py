"""``/healthz``: liveness, and a few numbers worth a glance."""

from __future__ import annotations

from fastapi import APIRouter, Request

from api.deps import ServiceDep, SettingsDep
from api.schemas import HealthOut, PlannerOut
from fleet.service.roles import HasFailover

router = APIRouter(tags=["health"])


@router.get("/healthz")
async def healthz(request: Request, service: ServiceDep, settings: SettingsDep) -> HealthOut:
    # async: reads only in-memory state, so no thread-pool hop (the failover fields too).
    failover: dict[str, object] = {}
    if isinstance(service, HasFailover):
        status = service.failover_status()
        failover = {"store": "postgresql", "role": status.role.value, "term": status.term,
                    "leader": status.leader, "service": status.service}  # fmt: skip
    return HealthOut(
        **failover,
        robots=len(service.robots()),
        yard=settings.yard,
        zenoh=list(getattr(request.app.state, "zenoh_locators", [])),
        auth=settings.api_token is not None,
        counters=dict(service.counters),
        planner=PlannerOut.of(service.planner_stats()),
        sizes=service.sizes(),
    )
