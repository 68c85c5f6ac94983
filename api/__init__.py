"""REST API of the fleet: ``api.app.create_app(settings)``, served by ``parkfleet serve``.

Kept import-free so ``parkfleet --help`` does not load FastAPI.
"""
