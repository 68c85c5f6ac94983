"""The operator's side of the dashboard in a real browser: the e-stop button and release,
pause / resume per robot and fleet-wide, the faults list, bays and keep-out zones drawn
with their state, a task's history in its details.

One ``parkfleet serve --site <example car park>`` and one ``parkfleet sim`` with two robots
serve the module; every test opens its own page and leaves the fleet released and resumed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from chromium import Console, Fleet, console_page, served_fleet

from fleet.core.geometry import segments_distance

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page

pytestmark = pytest.mark.integration

SITE = Path(__file__).resolve().parents[2] / "fleet" / "io" / "sites" / "carpark.toml"
WAIT_MS = 30_000
ARTIFACTS = Path(__file__).resolve().parents[2] / "artifacts"


@pytest.fixture(scope="module")
def fleet(browser: Browser, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    with served_fleet(tmp_path_factory.mktemp("operator"), 2, 5.0, "--site", str(SITE)) as f:
        yield f


@pytest.fixture
def page(browser: Browser, fleet: Fleet) -> Iterator[tuple[Page, Console]]:
    try:
        with console_page(browser, fleet.server.url, height=1000) as (opened, console):
            opened.wait_for_function(
                "window.__parkfleet.robots().filter(r => r.status !== 'lost').length >= 2",
                timeout=WAIT_MS,
            )
            yield opened, console
    finally:
        for action in ("release", "resume"):  # leave the fleet as found
            fleet.http.post(f"/control/{action}")


def statuses(page: Page) -> dict[str, str]:
    robots = page.evaluate("window.__parkfleet.robots()")
    return {r["id"]: r["status"] for r in robots}


def test_the_stop_button_stops_every_robot_until_released(
    page: tuple[Page, Console], fleet: Fleet
) -> None:
    browser_page, console = page
    from playwright.sync_api import expect

    banner = browser_page.locator("#estop-banner")
    expect(banner).to_be_hidden()
    stop = browser_page.get_by_role("button", name="EMERGENCY STOP", exact=True)
    expect(stop).to_be_visible()
    stop.click()
    browser_page.wait_for_function(
        "window.__parkfleet.robots().every(r => r.status === 'estop')", timeout=WAIT_MS
    )
    expect(banner).to_be_visible()
    expect(banner).to_contain_text("2 robots e-stopped")
    faults = browser_page.locator("#faults li.fault-fatal[data-code='estop']")
    expect(faults).to_have_count(2)
    expect(faults.first).to_contain_text("emergency stop by fleet-service")
    assert fleet.http.get("/control").json()["fleet"]["estop"] is True
    ARTIFACTS.mkdir(exist_ok=True)
    browser_page.screenshot(path=str(ARTIFACTS / "dashboard-estop.png"))
    for robot in fleet.http.get("/robots").json():  # the API says the same
        assert robot["status"] == "estop" and robot["u"] == 0.0
        assert [e["code"] for e in robot["errors"]] == ["estop"]

    browser_page.click("#estop-release")
    browser_page.wait_for_function(
        "window.__parkfleet.robots().every(r => r.status !== 'estop')", timeout=WAIT_MS
    )
    expect(banner).to_be_hidden()
    expect(browser_page.locator("#faults li")).to_have_count(0)
    assert console.errors == []


def test_pause_and_resume_one_robot_from_its_row_and_the_whole_fleet(
    page: tuple[Page, Console], fleet: Fleet
) -> None:
    browser_page, console = page
    from playwright.sync_api import expect

    row = browser_page.locator('#robots-body tr[data-robot-id="robot-1"]')
    row.locator("button[data-action='pause']").click()
    browser_page.wait_for_function(
        "window.__parkfleet.robots().find(r => r.id === 'robot-1').status === 'paused'",
        timeout=WAIT_MS,
    )
    expect(row).to_contain_text("paused by fleet-service")
    assert statuses(browser_page)["robot-2"] != "paused"
    row.locator("button[data-action='resume']").click()
    browser_page.wait_for_function(
        "window.__parkfleet.robots().find(r => r.id === 'robot-1').status !== 'paused'",
        timeout=WAIT_MS,
    )

    browser_page.click("#fleet-pause")
    browser_page.wait_for_function(
        "window.__parkfleet.robots().every(r => r.status === 'paused')", timeout=WAIT_MS
    )
    browser_page.click("#fleet-resume")
    browser_page.wait_for_function(
        "window.__parkfleet.robots().every(r => r.status !== 'paused')", timeout=WAIT_MS
    )
    assert console.errors == []


def test_bays_keep_out_zones_and_walls_are_drawn_with_their_state(
    page: tuple[Page, Console], fleet: Fleet
) -> None:
    browser_page, console = page
    browser_page.wait_for_function(
        "window.__parkfleet.drawn.bays === 17 && window.__parkfleet.drawn.zones === 3 "
        "&& window.__parkfleet.drawn.walls === 5 && window.__parkfleet.drawn.singleZones === 1 "
        "&& window.__parkfleet.drawn.lanes === 5"
    )
    assert [z["name"] for z in fleet.http.get("/zones").json()] == ["entrance"]
    canvas = browser_page.locator("#map")
    before = canvas.screenshot()
    created = fleet.http.post("/tasks", json={"bay": "A3"})
    assert created.status_code == 201, created.text
    browser_page.wait_for_function(
        "['reserved', 'occupied'].includes("
        "window.__parkfleet.bays().find(b => b.name === 'A3').status)",
        timeout=WAIT_MS,
    )
    assert canvas.screenshot() != before
    taken = fleet.http.post("/tasks", json={"bay": "A3"})
    assert taken.status_code == 409 and "bay A3 is taken" in taken.json()["detail"]
    assert console.errors == []


def test_a_tasks_details_show_its_history(page: tuple[Page, Console], fleet: Fleet) -> None:
    browser_page, console = page
    from playwright.sync_api import expect

    created = fleet.http.post("/tasks", json={"bay_group": "charging"})
    assert created.status_code == 201, created.text
    task_id = created.json()["id"]
    browser_page.wait_for_function(
        "id => window.__parkfleet.tasks().some(t => t.id === id && t.status !== 'queued')",
        arg=task_id,
        timeout=WAIT_MS,
    )
    browser_page.locator(f'#tasks-body tr[data-task-id="{task_id}"]').click()
    history = browser_page.locator("#dialog-history-body tr")
    expect(history.first).to_have_attribute("data-event", "created")
    expect(browser_page.locator("#dialog-history-body tr[data-event='assigned']")).to_have_count(1)
    expect(browser_page.locator("#dialog-history-body")).to_contain_text("robot-")
    browser_page.keyboard.press("Escape")
    assert console.errors == []


def test_a_task_behind_a_wall_drives_its_route_and_the_map_draws_it(
    page: tuple[Page, Console], fleet: Fleet
) -> None:
    browser_page, console = page
    site_obstacles = fleet.http.get("/obstacles").json()
    here = fleet.http.get("/robots/robot-1").json()["pose"]
    x, y = here["x"], here["y"]
    task_id = None
    try:
        # A wall 1.2 m from robot-1 across its way to a goal 3 m off, in the first direction
        # where the goal is valid (clear of the other robot, bays and keep-out zones).
        for dx, dy in ((1.0, 0.0), (-1.0, 0.0), (0.0, -1.0), (0.0, 1.0)):
            cx, cy = x + 1.2 * dx, y + 1.2 * dy
            wall = {"x": cx - 1.5 * dy, "y": cy - 1.5 * dx, "end": [cx + 1.5 * dy, cy + 1.5 * dx],
                    "radius": 0.3, "body": 0.05}  # fmt: skip
            put = fleet.http.put("/obstacles", json=[*site_obstacles, wall])
            assert put.status_code == 200, put.text
            goal = {"x": x + 3.0 * dx, "y": y + 3.0 * dy, "theta": math.atan2(dy, dx)}
            created = fleet.http.post("/tasks", json={"goal": goal, "robot_id": "robot-1"})
            if created.status_code == 201:
                task_id = created.json()["id"]
                break
        assert task_id is not None, "no direction with a valid goal"
        browser_page.wait_for_function(  # planned: the task's route reached the page
            "id => window.__parkfleet.tasks().some(t => t.id === id && t.route.length > 0)",
            arg=task_id,
            timeout=WAIT_MS,
        )
        browser_page.wait_for_function("window.__parkfleet.drawn.routes >= 1", timeout=WAIT_MS)
        browser_page.wait_for_function(
            f"window.__parkfleet.tasks().find(t => t.id === '{task_id}').status === 'succeeded'",
            timeout=4 * WAIT_MS,
        )
        # it went round the wall (by one of its ends, or along the site's lanes): the path
        # the fleet saw it drive never brought its body (0.25 m) to the wall's
        path = fleet.http.get(f"/tasks/{task_id}/path").json()
        driven = [(p["x"], p["y"]) for p in path]
        ends = ((wall["x"], wall["y"]), tuple(wall["end"]))
        assert math.dist(driven[-1], (goal["x"], goal["y"])) < 0.1
        assert min(segments_distance(a, b, *ends) for a, b in itertools.pairwise(driven)) > 0.3
        assert console.errors == []
    finally:
        if task_id is not None:
            fleet.http.post(f"/tasks/{task_id}/cancel")
        fleet.http.put("/obstacles", json=site_obstacles)
