"""/robots, /obstacles, /healthz and the OpenAPI docs."""

from __future__ import annotations

import httpx
import pytest

from fleet.service.bus import MemoryBus
from tests.api.conftest import add_robot

pytestmark = pytest.mark.anyio


async def test_robots_list_and_get(client: httpx.AsyncClient, bus: MemoryBus) -> None:
    add_robot(bus, "r2", x=1, y=2)
    add_robot(bus, "r1")
    robots = (await client.get("/robots")).json()
    assert [r["robot_id"] for r in robots] == ["r1", "r2"]
    r2 = await client.get("/robots/r2")
    assert r2.status_code == 200
    assert r2.json()["pose"] == {"x": 1.0, "y": 2.0, "theta": 0.0}
    assert r2.json()["status"] == "idle"
    assert {"last_seen", "task_id", "u", "omega", "law", "goal"} <= set(r2.json())


@pytest.mark.parametrize("robot_id", ["ghost", "a*b", "$x", "x%20y"])
async def test_unknown_robot_is_404(client: httpx.AsyncClient, robot_id: str) -> None:
    r = await client.get(f"/robots/{robot_id}")
    assert r.status_code == 404
    assert "detail" in r.json()


async def test_obstacles_put_then_get(client: httpx.AsyncClient) -> None:
    assert (await client.get("/obstacles")).json() == []
    body = [
        {"x": 1, "y": 2, "radius": 0.5, "body": 0.3},
        {"x": -3, "y": 0},
        {"x": -3, "y": 3, "end": [3, 3], "radius": 0.3, "body": 0.05},  # a wall segment
    ]
    r = await client.put("/obstacles", json=body)
    assert r.status_code == 200
    expected = [
        {"x": 1.0, "y": 2.0, "radius": 0.5, "body": 0.3, "end": None},
        {"x": -3.0, "y": 0.0, "radius": 1.0, "body": 0.1, "end": None},  # the default body
        {"x": -3.0, "y": 3.0, "radius": 0.3, "body": 0.05, "end": [3.0, 3.0]},
    ]
    assert r.json() == expected
    assert (await client.get("/obstacles")).json() == expected
    assert (await client.put("/obstacles", json=[])).json() == []


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('[{"x": 1, "y": 20}]', "0.y"),
        ('[{"x": 0, "y": 0}, {"x": NaN, "y": 0}]', "1.x"),
        ('[{"x": 0, "y": 0, "radius": 0}]', "0.radius"),
        ('[{"x": 0, "y": 0, "radius": Infinity}]', "0.radius"),
        ('[{"x": 0, "y": 0, "body": -0.1}]', "0.body"),
        ('[{"x": 0, "y": 0, "radius": 0.5, "body": 0.6}]', "body"),
        ('[{"x": 0, "y": 0, "end": [0, 30]}]', "0.end"),
        ('[{"x": 0, "y": 0, "end": [0, NaN]}]', "0.end.1"),
        ('[{"x": 0, "y": 0, "end": [1]}]', "0.end"),
        ('{"x": 0, "y": 0}', ""),
    ],
)
async def test_bad_obstacles_are_422(client: httpx.AsyncClient, text: str, field: str) -> None:
    r = await client.put(
        "/obstacles", content=text.encode(), headers={"Content-Type": "application/json"}
    )
    assert r.status_code == 422, r.text
    assert field in r.json()["detail"]


async def test_healthz(client: httpx.AsyncClient, bus: MemoryBus) -> None:
    add_robot(bus, "r1")
    r = await client.get("/healthz")
    assert r.status_code == 200
    body = r.json()
    assert body["status"] == "ok"
    assert body["robots"] == 1
    assert body["yard"] == [-10.0, 10.0, -5.0, 5.0]
    assert body["auth"] is False


async def test_docs_and_schema(client: httpx.AsyncClient) -> None:
    assert (await client.get("/docs")).status_code == 200
    schema = (await client.get("/openapi.json")).json()
    paths = schema["paths"]
    assert {"/tasks", "/tasks/{task_id}", "/tasks/{task_id}/cancel", "/robots"} <= set(paths)
    assert {"/robots/{robot_id}", "/obstacles", "/events", "/healthz"} <= set(paths)
    assert "201" in paths["/tasks"]["post"]["responses"]
    error_422 = schema["components"]["schemas"]["HTTPValidationError"]
    assert error_422["properties"]["detail"]["type"] == "string"
