"""The dashboard's routes: the page and its assets, ``/config``, and ``/tasks/{id}/plot.png``."""

from __future__ import annotations

import math
import threading

import httpx
import numpy as np
import pytest

from api.plot_cache import PlotCache
from api.rate_limit import TokenBucket
from api.routes.dashboard import ASSETS
from api.routes.plots import resample
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from tests.api.conftest import add_robot, api_client, drive, driven_task

pytestmark = pytest.mark.anyio

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


async def test_index_serves_the_page_with_its_module(client: httpx.AsyncClient) -> None:
    r = await client.get("/")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/html")
    assert '<script type="module" src="static/app.js">' in r.text


@pytest.mark.parametrize(
    ("name", "media_type"),
    [("app.js", "text/javascript"), ("map.js", "text/javascript"), ("style.css", "text/css")],
)
async def test_assets_are_served_with_their_media_type(
    client: httpx.AsyncClient, name: str, media_type: str
) -> None:
    r = await client.get(f"/static/{name}")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith(media_type)
    assert r.headers["cache-control"] == "no-cache"


@pytest.mark.parametrize("name", ["nope.js", "..%2Fapp.py", "..%2F..%2Fpyproject.toml"])
async def test_only_shipped_assets_are_served(client: httpx.AsyncClient, name: str) -> None:
    assert (await client.get(f"/static/{name}")).status_code == 404


def test_every_module_the_page_imports_ships() -> None:
    for name in ("index.html", "app.js", "api.js", "map.js", "style.css"):
        assert name in ASSETS


async def test_config_gives_yard_radii_and_auth(client: httpx.AsyncClient) -> None:
    body = (await client.get("/config")).json()
    assert body["yard"] == [-10.0, 10.0, -5.0, 5.0]  # the fixture's settings
    assert body["robot_radius"] > 0
    assert body["peer_radius"] > 0
    assert body["auth"] is False


async def test_config_tells_when_a_token_is_needed(auth_client: httpx.AsyncClient) -> None:
    assert (await auth_client.get("/config")).json()["auth"] is True


async def test_plot_of_an_unknown_task_is_404(client: httpx.AsyncClient) -> None:
    assert (await client.get("/tasks/nope/plot.png")).status_code == 404


async def test_plot_without_a_recorded_path_is_409(client: httpx.AsyncClient) -> None:
    task_id = (await client.post("/tasks", json={"goal": {"x": 1, "y": 1}})).json()["id"]
    r = await client.get(f"/tasks/{task_id}/plot.png")
    assert r.status_code == 409
    assert "no recorded path" in r.json()["detail"]


async def test_plot_of_a_driven_task_is_a_png(
    client: httpx.AsyncClient, fleet: FleetService, bus: MemoryBus
) -> None:
    task_id = await driven_task(client, fleet, bus, range(1, 40))
    r = await client.get(f"/tasks/{task_id}/plot.png")
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png"
    assert r.content.startswith(PNG_MAGIC)


async def test_plots_are_cached_and_renders_rate_limited(
    settings: Settings, fleet: FleetService, store: SqliteTaskStore, bus: MemoryBus
) -> None:
    one_render = {"api_plot_render_burst": 1, "api_plot_renders_per_s": 1e-6}
    async for client in api_client(settings.model_copy(update=one_render), fleet, store):
        plots: PlotCache = client._transport.app.state.plots  # type: ignore[attr-defined]
        add_robot(bus, "r1", 0.0, 0.0)
        body = {"goal": {"x": 2.0, "y": 1.0, "theta": 1.0}, "robot_id": "r1"}
        task_id = (await client.post("/tasks", json=body)).json()["id"]
        drive(fleet, bus, task_id, range(1, 21))
        url = f"/tasks/{task_id}/plot.png"
        first, again = await client.get(url), await client.get(url)
        assert first.status_code == again.status_code == 200
        assert again.content == first.content and plots.renders == 1  # the same path: cached
        drive(fleet, bus, task_id, range(21, 31))  # the path grows: a new image, over the rate
        limited = await client.get(url)
        assert limited.status_code == 429
        assert "rate-limited" in limited.json()["detail"]
        assert int(limited.headers["retry-after"]) > 0
        assert plots.renders == 1 and plots.refused == 1


def test_the_plot_cache_keeps_the_most_recently_used() -> None:
    cache = PlotCache(entries=2, rate=100.0, burst=10)
    for key in ("a", "b"):
        cache.render(key, key.encode)
    assert cache.get("a") == b"a"  # "a" used: "b" is now the oldest
    assert cache.render("c", lambda: b"c") == b"c"
    assert (cache.get("a"), cache.get("b"), cache.get("c")) == (b"a", None, b"c")
    assert cache.render("a", lambda: b"never drawn") == b"a"
    assert cache.renders == 3
    cache.close()


def test_plots_are_drawn_on_one_thread_whoever_asks() -> None:
    cache = PlotCache(entries=8, rate=100.0, burst=10)
    drawn_on: list[int] = []

    def draw() -> bytes:
        drawn_on.append(threading.get_ident())
        return b"png"

    askers = [threading.Thread(target=cache.render, args=(f"task-{k}", draw)) for k in range(4)]
    for t in askers:
        t.start()
    for t in askers:
        t.join()
    assert len(drawn_on) == 4 and len(set(drawn_on)) == 1
    assert drawn_on[0] not in {t.ident for t in askers}
    cache.close()


def test_token_bucket_allows_bursts_then_the_rate() -> None:
    now = [0.0]
    bucket = TokenBucket(rate=2.0, burst=3, clock=lambda: now[0])
    assert [bucket.take() for _ in range(3)] == [0.0, 0.0, 0.0]
    assert bucket.take() == pytest.approx(0.5)  # empty: the next token in 1/rate
    now[0] = 0.25
    assert bucket.take() == pytest.approx(0.25)
    now[0] = 0.5
    assert bucket.take() == 0.0
    now[0] = 100.0  # a long pause saves no more than the burst
    assert [bucket.take() for _ in range(4)] == [0.0, 0.0, 0.0, pytest.approx(0.5)]


def test_resample_is_uniform_and_keeps_the_ends() -> None:
    samples = [
        (100.0, 0.0, 0.0, 3.0, 1.0, 0.0),
        (100.1, 1.0, 0.0, -3.0, 1.0, 0.5),  # heading crosses ±π: unwrapped, not swung round
        (100.4, 1.0, 2.0, -2.9, 0.0, 1.0),
    ]
    poses, controls, dt = resample(samples, max_steps=8)
    assert poses.shape == (3, 3)  # at most one step per sample interval
    assert controls.shape == (2, 2)
    assert dt == pytest.approx(0.2)
    np.testing.assert_allclose(poses[0, :2], [0.0, 0.0])
    np.testing.assert_allclose(poses[-1, :2], [1.0, 2.0])
    assert poses[-1, 2] == pytest.approx(-2.9 + 2 * math.pi)
    assert np.all(np.abs(np.diff(poses[:, 2])) < 1.0)


def test_resample_needs_two_samples_spanning_time() -> None:
    with pytest.raises(ValueError):
        resample([(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)])
    with pytest.raises(ValueError):
        resample([(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)] * 3)
