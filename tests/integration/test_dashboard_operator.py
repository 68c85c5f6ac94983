"""The operator's side of the dashboard in a real browser: the e-stop button and release,
pause / resume per robot and fleet-wide, the faults list, bays and keep-out zones drawn
with their state, a task's history in its details.

One ``parkfleet serve --site <example car park>`` and one ``parkfleet sim`` with two robots
serve the module; every test opens its own page and leaves the fleet released and resumed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from chromium import Console, Fleet, console_page, served_fleet

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
        "&& window.__parkfleet.drawn.walls === 5"
    )
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
