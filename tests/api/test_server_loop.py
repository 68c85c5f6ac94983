"""The server's event loop and HTTP parser (api/server.py): uvloop and httptools."""

from __future__ import annotations

import asyncio

import pytest
import uvicorn
from fastapi import FastAPI

from api.server import run_loop


def test_the_server_runs_on_uvloop_and_returns_what_it_returned() -> None:
    uvloop = pytest.importorskip("uvloop")

    async def loop_type() -> type[asyncio.AbstractEventLoop]:
        return type(asyncio.get_running_loop())

    assert run_loop(loop_type()) is uvloop.Loop


def test_uvicorn_parses_the_servers_http_with_httptools() -> None:
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

    config = uvicorn.Config(FastAPI(), log_config=None)  # as api.server.serve builds it
    config.load()
    assert config.http_protocol_class is HttpToolsProtocol
