"""POST/GET /tasks and cancel: status codes, bodies and the validation contract."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from fleet.core.wire import Obstacle
from fleet.io.settings import Settings
from fleet.service.bus import MemoryBus
from fleet.service.fleet_service import FleetService
from fleet.service.store import SqliteTaskStore
from tests.api.conftest import add_robot, api_client, driven_task

pytestmark = pytest.mark.anyio


def raw_post(client: httpx.AsyncClient, path: str, text: str) -> Any:
    return client.post(path, content=text.encode(), headers={"Content-Type": "application/json"})


async def test_submit_returns_201_with_the_stored_task(client: httpx.AsyncClient) -> None:
    r = await client.post(
        "/tasks", json={"goal": {"x": 1.5, "y": -2.0, "theta": 0.5}, "direction": "cw"}
    )
    assert r.status_code == 201
    assert r.headers["content-type"] == "application/json"
    task = r.json()
    assert task["status"] == "queued"
    assert task["goal"] == {"x": 1.5, "y": -2.0, "theta": 0.5}
    assert task["direction"] == "cw"
    assert task["tolerance"] == {"position": 0.1, "heading": 0.1}
    assert task["revision"] == 0  # the law's re-plans under way (Task.revision)
    got = await client.get(f"/tasks/{task['id']}")
    assert got.status_code == 200
    assert got.json() == task


async def test_submit_passes_gains_tolerance_and_robot(
    client: httpx.AsyncClient, fleet: FleetService, bus: MemoryBus
) -> None:
    add_robot(bus, "r1", x=-3.0)
    body = {
        "goal": {"x": 0, "y": 0},
        "robot_id": "r1",
        "gains": {"kx": 2.6, "ky": 1.5, "ktheta": 1.5},
        "tolerance": {"position": 0.05, "heading": 0.02},
    }
    r = await client.post("/tasks", json=body)
    assert r.status_code == 201, r.text
    request = fleet.task(r.json()["id"]).request
    assert request.robot_id == "r1"
    assert request.gains is not None and request.gains.kx == 2.6
    assert request.tolerance.position == 0.05


async def test_idempotency_key_returns_the_same_task(
    client: httpx.AsyncClient, fleet: FleetService
) -> None:
    body = {"goal": {"x": 3, "y": 3}}
    first = await client.post("/tasks", json=body, headers={"Idempotency-Key": "abc"})
    again = await client.post("/tasks", json=body, headers={"Idempotency-Key": "abc"})
    assert first.status_code == again.status_code == 201
    assert first.json()["id"] == again.json()["id"]
    assert len(fleet.tasks()) == 1


async def test_list_filters_by_status_and_robot(client: httpx.AsyncClient) -> None:
    ids = [
        (await client.post("/tasks", json={"goal": {"x": x, "y": 0}})).json()["id"]
        for x in (1, 3, 5)
    ]
    assert (await client.post(f"/tasks/{ids[1]}/cancel")).status_code == 200
    assert [t["id"] for t in (await client.get("/tasks")).json()] == ids
    done = (await client.get("/tasks", params={"status": "cancelled"})).json()
    assert [t["id"] for t in done] == [ids[1]]
    queued = (await client.get("/tasks", params={"status": "queued"})).json()
    assert [t["id"] for t in queued] == [ids[0], ids[2]]
    assert (await client.get("/tasks", params={"robot_id": "nobody"})).json() == []
    newest = (await client.get("/tasks", params={"order": "newest", "limit": 2})).json()
    assert [t["id"] for t in newest] == ids[:0:-1]
    bad = await client.get("/tasks", params={"status": "sleeping"})
    assert bad.status_code == 422
    assert "status" in bad.json()["detail"]


async def _post_goals(client: httpx.AsyncClient, n: int) -> list[str]:
    """``n`` tasks on goals 1.5 m apart, in creation order."""
    ids = []
    for k in range(n):
        r = await client.post("/tasks", json={"goal": {"x": -9.0 + 1.5 * k, "y": 0.0}})
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    return ids


@pytest.mark.parametrize("order", ["oldest", "newest"])
async def test_pages_follow_the_link_header(client: httpx.AsyncClient, order: str) -> None:
    ids = await _post_goals(client, 7)
    url: str | None = f"/tasks?order={order}&limit=3"
    pages = []
    while url is not None:
        r = await client.get(url)
        assert r.status_code == 200
        pages.append([t["id"] for t in r.json()])
        url = r.links.get("next", {}).get("url")
    assert [len(p) for p in pages] == [3, 3, 1]  # no Link after the last page
    assert [i for page in pages for i in page] == (ids if order == "oldest" else ids[::-1])


async def test_a_page_is_capped_by_the_setting(
    settings: Settings, fleet: FleetService, store: SqliteTaskStore
) -> None:
    capped = settings.model_copy(update={"api_tasks_page_max": 2})
    async for client in api_client(capped, fleet, store):
        ids = await _post_goals(client, 3)
        r = await client.get("/tasks")  # no limit given: still one capped page
        assert [t["id"] for t in r.json()] == ids[:2]
        assert "next" in r.links
        too_many = await client.get("/tasks", params={"limit": 3})
        assert too_many.status_code == 422
        assert too_many.json()["errors"][0]["loc"] == ["query", "limit"]
        assert "at most 2" in too_many.json()["detail"]


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"status": "asleep"}, "status"),
        ({"robot_id": "r" * 201}, "robot_id"),
        ({"order": "random"}, "order"),
        ({"limit": 0}, "limit"),
        ({"limit": "ten"}, "limit"),
    ],
)
async def test_a_bad_list_parameter_is_422_naming_it(
    client: httpx.AsyncClient, params: dict[str, Any], field: str
) -> None:
    r = await client.get("/tasks", params=params)
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["loc"] == ["query", field]
    assert r.json()["detail"].startswith(f"{field}: ")


@pytest.mark.parametrize("cursor", ["nope", "W10", "WzEsMl0", "eyJhIjogMX0", "WyJ4IiwgImEiXQ"])
async def test_a_cursor_not_made_by_the_api_is_422(client: httpx.AsyncClient, cursor: str) -> None:
    r = await client.get("/tasks", params={"cursor": cursor})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["query", "cursor"]


@pytest.mark.parametrize("field", ["x", "y", "theta"])
@pytest.mark.parametrize("value", ["NaN", "Infinity", "-Infinity", "1e400"])
async def test_non_finite_numbers_are_422_naming_the_field(
    client: httpx.AsyncClient, field: str, value: str
) -> None:
    goal = {"x": "1", "y": "1", "theta": "0"} | {field: value}
    text = '{"goal": {' + ", ".join(f'"{k}": {v}' for k, v in goal.items()) + "}}"
    r = await raw_post(client, "/tasks", text)
    assert r.status_code == 422
    body = r.json()
    assert f"goal.{field}" in body["detail"]
    assert body["errors"][0]["loc"] == ["body", "goal", field]


@pytest.mark.parametrize(
    ("goal", "where"),
    [
        ({"x": 10.5, "y": 0}, "(10.50, 0.00)"),
        ({"x": 0, "y": -5.01}, "(0.00, -5.01)"),
        ({"x": -11, "y": 9}, "(-11.00, 9.00)"),
    ],
)
async def test_out_of_yard_goal_is_409_goal_rejected_with_the_reason(
    client: httpx.AsyncClient, goal: dict[str, float], where: str
) -> None:
    """A well-formed goal the yard rejects is a 409 (as one in an obstacle's zone), not a
    422: 422 is for malformed fields."""
    r = await client.post("/tasks", json={"goal": goal})
    assert r.status_code == 409, r.text
    assert r.json() == {
        "detail": f"goal {where} is outside the yard x in [-10, 10], y in [-5, 5] m"
    }


async def test_goal_bounds_are_not_in_the_schema_but_obstacle_bounds_are(
    client: httpx.AsyncClient,
) -> None:
    """The OpenAPI schema matches the codes: a goal outside the yard is well-formed (409),
    an obstacle centre outside it is not (422)."""
    schema = (await client.get("/openapi.json")).json()
    components = schema["components"]["schemas"]
    assert "maximum" not in components["PoseIn"]["properties"]["x"]
    assert components["ObstacleIn"]["properties"]["x"]["maximum"] == 10.0
    responses = schema["paths"]["/tasks"]["post"]["responses"]
    assert {"201", "401", "404", "409", "422"} <= set(responses)
    assert "outside the yard" in responses["409"]["description"]


async def test_yard_edges_are_inside(client: httpx.AsyncClient) -> None:
    r = await client.post("/tasks", json={"goal": {"x": 10, "y": -5}})
    assert r.status_code == 201


@pytest.mark.parametrize(
    "body",
    [
        "{}",
        '{"goal": {"x": 1}}',
        '{"goal": {"x": "one", "y": 1}}',
        '{"goal": {"x": 1, "y": 1}, "speed": 3}',
        '{"goal": {"x": 1, "y": 1}, "direction": "sideways"}',
        '{"goal": {"x": 1, "y": 1}, "robot_id": "a/b*"}',
        '{"goal": {"x": 1, "y": 1}, "gains": {"kx": 0, "ky": 1, "ktheta": 1}}',
        '{"goal": {"x": 1, "y": 1}, "gains": {"kx": 1, "ky": 1, "ktheta": NaN}}',
        '{"goal": {"x": 1, "y": 1}, "tolerance": {"position": -1, "heading": 0.1}}',
        '{"goal": {"x": 1, "y": 1, "theta": 100}}',
        "[1, 2]",
        "not json",
        '{"goal": ',
    ],
)
async def test_bad_bodies_are_422(client: httpx.AsyncClient, body: str) -> None:
    r = await raw_post(client, "/tasks", body)
    assert r.status_code == 422, r.text
    assert isinstance(r.json()["detail"], str)


async def test_unknown_robot_is_404(client: httpx.AsyncClient) -> None:
    r = await client.post("/tasks", json={"goal": {"x": 1, "y": 1}, "robot_id": "ghost"})
    assert r.status_code == 404
    assert "ghost" in r.json()["detail"]


async def test_unknown_task_is_404(client: httpx.AsyncClient) -> None:
    assert (await client.get("/tasks/nope")).status_code == 404
    assert (await client.post("/tasks/nope/cancel")).status_code == 404
    assert (await client.get("/tasks/nope/path")).status_code == 404


async def test_goal_in_obstacle_zone_is_409_with_reason(
    client: httpx.AsyncClient, fleet: FleetService
) -> None:
    fleet.set_obstacles([Obstacle(x=2, y=2, radius=1.0)])
    r = await client.post("/tasks", json={"goal": {"x": 2.5, "y": 2}})
    assert r.status_code == 409
    assert "obstacle" in r.json()["detail"]


async def test_goal_near_another_goal_is_409(client: httpx.AsyncClient) -> None:
    assert (await client.post("/tasks", json={"goal": {"x": 1, "y": 1}})).status_code == 201
    r = await client.post("/tasks", json={"goal": {"x": 1.5, "y": 1}})
    assert r.status_code == 409
    assert "apart" in r.json()["detail"]


async def test_cancel_then_cancel_again_is_409(client: httpx.AsyncClient) -> None:
    task_id = (await client.post("/tasks", json={"goal": {"x": 1, "y": 1}})).json()["id"]
    r = await client.post(f"/tasks/{task_id}/cancel")
    assert r.status_code == 200
    assert r.json()["status"] == "cancelled"
    again = await client.post(f"/tasks/{task_id}/cancel")
    assert again.status_code == 409
    assert "cancelled" in again.json()["detail"]


async def test_path_of_a_task_not_driven_yet_is_409(client: httpx.AsyncClient) -> None:
    task_id = (await client.post("/tasks", json={"goal": {"x": 1, "y": 1}})).json()["id"]
    r = await client.get(f"/tasks/{task_id}/path")
    assert r.status_code == 409  # no robot has driven it yet
    assert r.json() == {
        "detail": f"task {task_id} has no recorded path (queued): a path is recorded while a "
        "robot drives the task, and only for the most recent tasks"
    }
    responses = (await client.get("/openapi.json")).json()["paths"]["/tasks/{task_id}/path"]
    assert {"200", "404", "409"} <= set(responses["get"]["responses"])


async def test_path_of_a_driven_task_is_200(
    client: httpx.AsyncClient, fleet: FleetService, bus: MemoryBus
) -> None:
    task_id = await driven_task(client, fleet, bus, range(1, 10))
    r = await client.get(f"/tasks/{task_id}/path")
    assert r.status_code == 200, r.text
    points = r.json()
    assert points and set(points[0]) == {"t", "x", "y", "theta", "u", "omega"}
    assert points[-1]["x"] == pytest.approx(2.0 * 9 / 40)
