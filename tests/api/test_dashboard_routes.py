"""The dashboard's routes: the page and its assets, ``/config``, and ``/tasks/{id}/plot.png``."""

from __future__ import annotations

import asyncio
import math
import time

import httpx
import numpy as np
import pytest

from api.routes.dashboard import ASSETS
from api.routes.plots import resample
from fleet.core.wire import Pose, RobotMode, RobotState
from fleet.service.bus import MemoryBus
from tests.api.conftest import add_robot

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


async def _assigned(client: httpx.AsyncClient, task_id: str) -> None:
    deadline = time.monotonic() + 10
    while (await client.get(f"/tasks/{task_id}")).json()["status"] == "queued":
        assert time.monotonic() < deadline, "the service never assigned the task"
        await asyncio.sleep(0.02)


async def test_plot_of_a_driven_task_is_a_png(client: httpx.AsyncClient, bus: MemoryBus) -> None:
    add_robot(bus, "r1", 0.0, 0.0)
    body = {"goal": {"x": 2.0, "y": 1.0, "theta": 1.0}, "robot_id": "r1"}
    task_id = (await client.post("/tasks", json=body)).json()["id"]
    await _assigned(client, task_id)
    for k in range(1, 40):
        s = k / 40
        bus.deliver_state(
            RobotState(
                robot_id="r1",
                seq=k,
                stamp=time.time(),
                pose=Pose(x=2.0 * s, y=1.0 * s, theta=s),
                u=0.5,
                omega=0.2,
                mode=RobotMode.ARRIVED if k == 39 else RobotMode.DRIVING,
                task_id=task_id,
            )
        )
    r = await client.get(f"/tasks/{task_id}/plot.png")
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png"
    assert r.content.startswith(PNG_MAGIC)


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
