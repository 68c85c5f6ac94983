"""Bearer-token auth on mutating endpoints, and the loopback-only default of serve."""

from __future__ import annotations

import httpx
import pytest
from pydantic import SecretStr

from api.server import check_bind, is_loopback
from fleet.cli.main import main
from fleet.io.settings import load_settings
from tests.api.conftest import TOKEN

pytestmark = pytest.mark.anyio

GOAL = {"goal": {"x": 1, "y": 1}}


@pytest.mark.parametrize(
    "headers",
    [
        {},
        {"Authorization": "Bearer wrong"},
        {"Authorization": f"Bearer {TOKEN}x"},
        {"Authorization": f"Basic {TOKEN}"},
        {"Authorization": TOKEN},
        {"Authorization": "Bearer "},
    ],
)
async def test_mutations_need_the_token(
    auth_client: httpx.AsyncClient, headers: dict[str, str]
) -> None:
    for r in (
        await auth_client.post("/tasks", json=GOAL, headers=headers),
        await auth_client.post("/tasks/t1/cancel", headers=headers),
        await auth_client.put("/obstacles", json=[], headers=headers),
    ):
        assert r.status_code == 401
        assert r.headers["WWW-Authenticate"] == "Bearer"
        assert r.json() == {"detail": "missing or wrong bearer token"}


async def test_right_token_is_accepted(auth_client: httpx.AsyncClient) -> None:
    headers = {"Authorization": f"Bearer {TOKEN}"}
    created = await auth_client.post("/tasks", json=GOAL, headers=headers)
    assert created.status_code == 201
    cancel = await auth_client.post(f"/tasks/{created.json()['id']}/cancel", headers=headers)
    assert cancel.status_code == 200
    assert (await auth_client.put("/obstacles", json=[], headers=headers)).status_code == 200


async def test_reads_need_no_token(auth_client: httpx.AsyncClient) -> None:
    for path in ("/tasks", "/robots", "/obstacles", "/healthz"):
        assert (await auth_client.get(path)).status_code == 200
    assert (await auth_client.get("/healthz")).json()["auth"] is True


async def test_no_token_configured_means_open(client: httpx.AsyncClient) -> None:
    assert (await client.post("/tasks", json=GOAL)).status_code == 201


@pytest.mark.parametrize(
    ("host", "loopback"),
    [
        ("127.0.0.1", True),
        ("127.1.2.3", True),
        ("localhost", True),
        ("::1", True),
        ("[::1]", True),
        ("0.0.0.0", False),
        ("::", False),
        ("192.168.1.10", False),
        ("fleet.example.org", False),
    ],
)
def test_is_loopback(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback


def test_check_bind_refuses_exposed_address_without_token() -> None:
    with pytest.raises(ValueError, match="PARKFLEET_API_TOKEN"):
        check_bind(load_settings(api_host="0.0.0.0"))
    check_bind(load_settings(api_host="0.0.0.0", api_token=SecretStr("t")))
    check_bind(load_settings())  # 127.0.0.1 by default
    assert load_settings().api_host == "127.0.0.1"


def test_serve_exits_2_on_exposed_address_without_token(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("PARKFLEET_API_TOKEN", raising=False)
    assert main(["serve", "--host", "0.0.0.0", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert "refusing to serve on non-loopback address '0.0.0.0'" in err
