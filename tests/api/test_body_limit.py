"""Request bodies are capped (413) before anything is parsed, for every client.

FastAPI parses a body before the bearer-token dependency runs: the cap is what keeps an
unauthenticated client from making the server hold a body of any size.
"""

from __future__ import annotations

import json
from collections.abc import AsyncIterator

import httpx
import pytest
from pydantic import SecretStr

from fleet.io.settings import Settings
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from tests.api.conftest import TOKEN, api_client

pytestmark = pytest.mark.anyio

CAP = 4096
CHUNK = 1024


@pytest.fixture
async def capped(
    settings: Settings, fleet: FleetService, store: SqliteTaskStore
) -> AsyncIterator[httpx.AsyncClient]:
    """A client of an app with a 4 KiB body cap and an API token (this client has none)."""
    update = {"api_max_body_bytes": CAP, "api_token": SecretStr(TOKEN)}
    async for client in api_client(settings.model_copy(update=update), fleet, store):
        yield client


def padded_task(size: int) -> bytes:
    """A valid task body of exactly ``size`` bytes (JSON whitespace as padding)."""
    body = json.dumps({"goal": {"x": 1.0, "y": 1.0}}).encode()
    return body[:-1] + b" " * (size - len(body)) + b"}"


class Sender:
    """A streamed (chunked, no Content-Length) body; counts the chunks taken from it."""

    def __init__(self, chunks: int) -> None:
        self.chunks = chunks
        self.taken = 0

    async def __aiter__(self) -> AsyncIterator[bytes]:
        for _ in range(self.chunks):
            self.taken += 1
            yield b" " * CHUNK


async def test_a_declared_length_over_the_cap_is_413_before_auth(
    capped: httpx.AsyncClient,
) -> None:
    r = await capped.post(
        "/tasks", content=padded_task(CAP + 1), headers={"Content-Type": "application/json"}
    )
    assert r.status_code == 413  # not 401: the body is refused before anything looks at it
    assert f"larger than {CAP} bytes" in r.json()["detail"]
    assert r.headers["connection"] == "close"


async def test_a_streamed_body_is_cut_off_at_the_cap_not_read_to_the_end(
    capped: httpx.AsyncClient,
) -> None:
    sender = Sender(chunks=1000)  # 1 MB on offer
    r = await capped.post("/tasks", content=sender, headers={"Content-Type": "application/json"})
    assert r.status_code == 413
    assert sender.taken <= CAP // CHUNK + 1  # read up to the first chunk past the cap


async def test_a_streamed_body_to_any_route_is_capped(capped: httpx.AsyncClient) -> None:
    sender = Sender(chunks=1000)
    r = await capped.put("/obstacles", content=sender)
    assert r.status_code == 413
    assert sender.taken <= CAP // CHUNK + 1


async def test_a_body_at_the_cap_is_parsed_as_usual(capped: httpx.AsyncClient) -> None:
    headers = {"Content-Type": "application/json"}
    r = await capped.post("/tasks", content=padded_task(CAP), headers=headers)
    assert r.status_code == 401  # read and parsed; then the missing token counts
    auth = headers | {"Authorization": f"Bearer {TOKEN}"}
    r = await capped.post("/tasks", content=padded_task(CAP), headers=auth)
    assert r.status_code == 201, r.text
