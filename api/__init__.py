"""REST API of the fleet: ``api.app.create_app(settings)``, served by ``parkfleet serve``.

- :mod:`~api.app`: ``create_app`` and its lifespan (router session, store, bus, service).
- :mod:`~api.routes`: one router per resource; :mod:`~api.schemas`: input and output
  models; :mod:`~api.deps`: dependencies (auth, service); :mod:`~api.errors`: error bodies;
  :mod:`~api.streaming`: Server-Sent Events; :mod:`~api.server`: uvicorn; ``static/``: the
  dashboard.
- Bounds (``api_*`` settings): :mod:`~api.body_limit` (request bodies, before parsing),
  :mod:`~api.paging` (cursors of the task list), :mod:`~api.plot_cache` and
  :mod:`~api.rate_limit` (plot renders); the event-stream caps live in :mod:`~api.streaming`.

Kept import-free so ``parkfleet --help`` does not load FastAPI.
"""

__all__: list[str] = []
