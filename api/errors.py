"""Exception handlers: domain errors to status codes, and a 422 body that always serialises.

Every error body is ``{"detail": "<reason>"}``; a 422 adds ``errors`` (one per field).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, HTTPException, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from api.schemas import FieldError, ValidationErrorOut
from fleet.core.tasks import (
    BayNotFound,
    BayTaken,
    FleetError,
    GoalRejected,
    RobotNotFound,
    TaskConflict,
    TaskNotFound,
)
from fleet.service.roles import NotLeader

_log = logging.getLogger(__name__)

STATUS_OF: dict[type[FleetError], int] = {
    TaskNotFound: status.HTTP_404_NOT_FOUND,
    RobotNotFound: status.HTTP_404_NOT_FOUND,
    BayNotFound: status.HTTP_404_NOT_FOUND,
    BayTaken: status.HTTP_409_CONFLICT,
    GoalRejected: status.HTTP_409_CONFLICT,
    TaskConflict: status.HTTP_409_CONFLICT,
}


def retry_later(code: int, reason: str, after_s: float) -> HTTPException:
    """A refusal for now (429, 503) with ``Retry-After``: whole seconds, at least one."""
    return HTTPException(code, reason, headers={"Retry-After": str(max(1, math.ceil(after_s)))})


def _field_name(loc: Sequence[Any]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header"):
        parts = parts[1:] or parts
    return ".".join(parts) or "request"


def validation_body(errors: Sequence[Any]) -> ValidationErrorOut:
    """The 422 body. The offending ``input`` is left out on purpose: it may be NaN or
    Infinity (Python's json accepts them), which a strict JSON response cannot carry."""
    fields = [
        FieldError(
            loc=[p if isinstance(p, int) else str(p) for p in e.get("loc", ())],
            msg=str(e.get("msg", "invalid")),
            type=str(e.get("type", "value_error")),
        )
        for e in errors
    ]
    detail = "; ".join(f"{_field_name(f.loc)}: {f.msg}" for f in fields) or "invalid request"
    return ValidationErrorOut(detail=detail, errors=fields)


async def _on_validation_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    body = validation_body(exc.errors())
    return JSONResponse(body.model_dump(), status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)


async def _on_fleet_error(request: Request, exc: Exception) -> JSONResponse:
    code = next(
        (c for kind, c in STATUS_OF.items() if isinstance(exc, kind)), status.HTTP_409_CONFLICT
    )
    return JSONResponse({"detail": str(exc) or type(exc).__name__}, status_code=code)


async def _on_unexpected(request: Request, exc: Exception) -> JSONResponse:
    _log.exception("unhandled error in %s %s", request.method, request.url.path)
    return JSONResponse({"detail": "internal error"}, status_code=500)


async def _on_not_leader(request: Request, exc: Exception) -> JSONResponse:
    """A write sent to a standby: 503, the leader's API in ``X-Parkfleet-Leader`` (if one is
    elected) and in the reason; retry there (or here after a take-over)."""
    assert isinstance(exc, NotLeader)
    headers = {"Retry-After": "1"}
    if exc.address:
        headers["X-Parkfleet-Leader"] = exc.address
    return JSONResponse(
        {"detail": str(exc), "leader": exc.address},
        status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
        headers=headers,
    )


def install(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _on_validation_error)
    app.add_exception_handler(NotLeader, _on_not_leader)
    app.add_exception_handler(FleetError, _on_fleet_error)
    app.add_exception_handler(Exception, _on_unexpected)
