"""The FastAPI application: ``create_app(settings)``.

Its lifespan owns the fleet, opened by :func:`fleet.service.host.open_fleet` (the Zenoh
router session, the task store, the Zenoh bus, the fleet service and the heap trimmer, in
that order) and closed in reverse however startup or shutdown goes (an unclosed Zenoh
session would hang interpreter exit). What a client can
make the server hold is bounded by the ``api_*`` settings: request bodies
(:mod:`api.body_limit`), event streams (:mod:`api.streaming`), task pages
(:mod:`api.routes.tasks`) and plot renders (:mod:`api.plot_cache`).
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import ExitStack, asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

from api import errors
from api.body_limit import BodyLimit
from api.deps import FleetAPI
from api.metrics import FleetMetrics
from api.plot_cache import PlotCache
from api.routes import (
    bays,
    control,
    dashboard,
    events,
    health,
    metrics,
    obstacles,
    plots,
    robots,
    tasks,
)
from api.schemas import ValidationErrorOut
from api.streaming import EventHub
from fleet.io.settings import Settings
from fleet.service.host import StoreFactory, open_fleet, sqlite_store
from fleet.service.store import TaskStore

_log = logging.getLogger(__name__)

DESCRIPTION = """\
Parking tasks for a fleet of self-parking robots (Lyapunov posture control, laws (17)
ccw and (20) cw). When `PARKFLEET_API_TOKEN` is set, POST and PUT need
`Authorization: Bearer <token>`. Every error body is `{"detail": "..."}`.
"""


def create_app(
    settings: Settings,
    *,
    service: FleetAPI | None = None,
    store: TaskStore | None = None,
    store_factory: StoreFactory = sqlite_store,
) -> FastAPI:
    """The API app. With ``service`` and its ``store`` given (tests), the lifespan uses
    them and opens nothing; else it opens the fleet with ``store_factory``'s store."""
    if (service is None) != (store is None):
        raise ValueError("create_app: give both the service and its task store, or neither")
    hub = EventHub(
        max_backlog=settings.api_sse_queue_frames, max_clients=settings.api_sse_max_clients
    )

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        with ExitStack() as stack:
            if service is None:
                try:
                    fleet = stack.enter_context(open_fleet(settings, store=store_factory))
                    app.state.service, app.state.tasks = fleet.service, fleet.store
                    app.state.zenoh_locators = fleet.locators
                except Exception as exc:
                    app.state.startup_error = exc  # for the CLI's one-line error
                    raise
                _log.info("fleet service up; Zenoh router on %s", app.state.zenoh_locators)
            else:
                app.state.service, app.state.tasks, app.state.zenoh_locators = service, store, []
            app.state.metrics = FleetMetrics(app.state.service)  # a registry per app
            stack.callback(app.state.metrics.close)
            try:
                yield
            finally:
                hub.close()
                app.state.plots.close()
                app.state.service = app.state.tasks = None

    app = FastAPI(
        title="parkfleet",
        version="0.1.0",
        description=DESCRIPTION,
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.events = hub
    app.state.plots = PlotCache(
        settings.api_plot_cache_entries,
        settings.api_plot_renders_per_s,
        settings.api_plot_render_burst,
    )
    app.state.service = None
    app.state.tasks = None
    app.state.zenoh_locators = []
    app.state.startup_error = None
    errors.install(app)
    app.add_middleware(BodyLimit, max_bytes=settings.api_max_body_bytes)
    for module in (tasks, robots, control, bays, obstacles, events, health):
        app.include_router(module.router)
    app.include_router(plots.router)
    app.include_router(metrics.router)
    app.include_router(dashboard.router)
    _document_validation_errors(app)
    return app


def _publish_yard(components: dict[str, Any], yard: tuple[float, float, float, float]) -> None:
    """Write the configured yard into the obstacle centres' bounds (clients, fuzzers): one
    outside is a 422. A goal's are not bounds of the schema: outside the yard it is well-formed
    and rejected by the service (409), as one in an obstacle's zone is."""
    xmin, xmax, ymin, ymax = yard
    props = components.get("ObstacleIn", {}).get("properties", {})
    for name, low, high in (("x", xmin, xmax), ("y", ymin, ymax)):
        if name in props:
            props[name] |= {"minimum": low, "maximum": high}


def _document_validation_errors(app: FastAPI) -> None:
    """Make the OpenAPI schema describe our 422 body instead of FastAPI's default one, and
    the configured yard as the bounds of every obstacle centre."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = get_openapi(
                title=app.title,
                version=app.version,
                description=app.description,
                routes=app.routes,
            )
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            own = ValidationErrorOut.model_json_schema(ref_template="#/components/schemas/{model}")
            components.update(own.pop("$defs", {}))
            components["HTTPValidationError"] = own
            components.pop("ValidationError", None)
            _publish_yard(components, app.state.settings.yard)
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
