"""Request bodies capped at ``api_max_body_bytes``, counted as they stream, before parsing.

FastAPI reads (and parses) a request's body before any dependency runs, the bearer-token
check included, so without a cap an unauthenticated client could make the server hold a
body of any size. :class:`BodyLimit` is a plain ASGI middleware in front of the app:

* a ``Content-Length`` over the cap is answered 413 at once, nothing read;
* otherwise (chunked bodies, or a client that sends more than it declared) the bytes are
  counted as the app receives them, and the first chunk past the cap ends the request with
  a 413; the rest is never read.

The 413 carries ``Connection: close`` so the server does not read the unread body either.
"""

from __future__ import annotations

from fastapi import HTTPException, status
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send


class BodyTooLarge(HTTPException):
    """The body passed the cap (an ``HTTPException``: FastAPI lets it through its body
    parsing untouched, and its handler answers 413)."""

    def __init__(self, max_bytes: int) -> None:
        super().__init__(
            status.HTTP_413_CONTENT_TOO_LARGE,
            f"request body larger than {max_bytes} bytes (api_max_body_bytes)",
            headers={"Connection": "close"},
        )


class BodyLimit:
    """ASGI middleware: 413 for any HTTP request body over ``max_bytes``."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = _content_length(scope)
        if declared is not None and declared > self.max_bytes:
            await self._reject(scope, receive, send)
            return
        received = 0
        started = False

        async def counted_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise BodyTooLarge(self.max_bytes)
            return message

        async def watched_send(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, counted_receive, watched_send)
        except BodyTooLarge:
            if started:  # the app had answered already: nothing more to say
                raise
            await self._reject(scope, receive, send)

    async def _reject(self, scope: Scope, receive: Receive, send: Send) -> None:
        error = BodyTooLarge(self.max_bytes)
        response = JSONResponse({"detail": error.detail}, error.status_code, error.headers)
        await response(scope, receive, send)


def _content_length(scope: Scope) -> int | None:
    """The declared body size, if a valid ``Content-Length`` header gives one."""
    for name, value in scope.get("headers", ()):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None  # the server itself rejects malformed lengths
    return None
