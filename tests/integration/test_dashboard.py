"""The dashboard in a real browser: Debian's headless Chromium driven by Playwright.

One ``parkfleet serve`` (free ports, fresh data directory) and one ``parkfleet sim`` with two
robots serve the whole module; every test opens its own page. Without chromium or the
``playwright`` package the tests skip locally and fail under ``CI=true``. A screenshot of
the console goes to ``artifacts/dashboard.png``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import httpx
import pytest
from chromium import Console, Fleet, console_page, served_fleet

from fleet.io.processes import running_server

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page

pytestmark = pytest.mark.integration

ARTIFACTS = Path(__file__).resolve().parents[2] / "artifacts"
TIME_SCALE = "5"
TASK_TIMEOUT_MS = 90_000


@pytest.fixture(scope="module")
def fleet(browser: Browser, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    """``parkfleet serve`` plus ``parkfleet sim --robots 2`` connected to its router."""
    with served_fleet(tmp_path_factory.mktemp("dashboard"), 2, float(TIME_SCALE)) as fleet:
        yield fleet


@pytest.fixture
def page(browser: Browser, fleet: Fleet) -> Iterator[tuple[Page, Console]]:
    with console_page(browser, fleet.server.url) as opened:
        yield opened


def _wait_for_robots(page: Page, n: int) -> list[dict[str, Any]]:
    page.wait_for_function(
        "n => window.__parkfleet.robots().filter(r => r.status !== 'lost').length >= n",
        arg=n,
        timeout=30_000,
    )
    robots: list[dict[str, Any]] = page.evaluate("window.__parkfleet.robots()")
    return robots


def test_page_loads_without_console_errors(page: tuple[Page, Console]) -> None:
    browser_page, console = page
    from playwright.sync_api import expect

    _wait_for_robots(browser_page, 2)
    assert browser_page.title().startswith("parkfleet")
    expect(browser_page.locator("#conn")).to_have_attribute("data-state", "live")
    # The table is drawn on animation frames (throttled), after the state holds the robots:
    # wait for the rows rather than reading them once.
    expect(browser_page.locator("#robots-body tr")).to_have_count(2)
    expect(browser_page.locator("#legend-modes li")).to_have_count(9)  # one per robot status
    assert console.errors == []


def test_robots_move_on_the_map(page: tuple[Page, Console], fleet: Fleet) -> None:
    browser_page, console = page
    start = {r["id"]: (r["x"], r["y"]) for r in _wait_for_robots(browser_page, 2)}
    canvas = browser_page.locator("#map")
    before = canvas.screenshot()
    created = fleet.http.post("/tasks", json={"goal": {"x": -4.0, "y": -3.0, "theta": 0.0}})
    assert created.status_code == 201, created.text
    browser_page.wait_for_function(
        """start => window.__parkfleet.robots().some(
            r => r.id in start && Math.hypot(r.x - start[r.id][0], r.y - start[r.id][1]) > 0.5
               && r.trail > 1)""",
        arg=start,
        timeout=30_000,
    )
    assert canvas.screenshot() != before  # the move shows on the canvas, not only in state
    assert console.errors == []


def test_task_submitted_on_the_map_reaches_succeeded(
    page: tuple[Page, Console], fleet: Fleet
) -> None:
    browser_page, console = page
    _wait_for_robots(browser_page, 2)
    from playwright.sync_api import expect

    # Click at (3, 2) m and drag straight up: heading +90°.
    x, y = browser_page.evaluate("window.__parkfleet.worldToPage(3, 2)")
    browser_page.mouse.move(x, y)
    browser_page.mouse.down()
    browser_page.mouse.move(x + 5, y - 40, steps=4)
    browser_page.mouse.move(x, y - 90, steps=4)
    browser_page.mouse.up()
    assert float(browser_page.input_value("#goal-x")) == pytest.approx(3.0, abs=0.05)
    assert float(browser_page.input_value("#goal-y")) == pytest.approx(2.0, abs=0.05)
    assert float(browser_page.input_value("#goal-theta")) == pytest.approx(90.0, abs=1.0)
    browser_page.select_option("#goal-direction", "ccw")
    browser_page.click("#submit-task")
    expect(browser_page.locator("#form-message")).to_contain_text("Task ")

    tasks = browser_page.evaluate("window.__parkfleet.tasks()")
    mine = [
        t for t in tasks if abs(t["goal"]["x"] - 3.0) < 0.05 and abs(t["goal"]["y"] - 2.0) < 0.05
    ]
    assert len(mine) == 1, tasks
    task_id = mine[0]["id"]
    row = browser_page.locator(f'#tasks-body tr[data-task-id="{task_id}"]')
    expect(row).to_be_visible()
    final = browser_page.wait_for_function(
        """id => {
            const row = document.querySelector(`#tasks-body tr[data-task-id="${id}"]`);
            const status = row?.dataset.status;
            return ["succeeded", "failed", "cancelled"].includes(status) && status;
        }""",
        arg=task_id,
        timeout=TASK_TIMEOUT_MS,
    ).json_value()
    assert final == "succeeded", row.inner_text()
    expect(row.locator(".law")).to_have_text("ccw")

    stored = fleet.http.get(f"/tasks/{task_id}").json()  # the page showed what the API holds
    assert stored["status"] == "succeeded"
    assert stored["direction"] == "ccw"
    assert stored["goal"]["theta"] == pytest.approx(math.pi / 2, abs=0.02)
    plot = fleet.http.get(f"/tasks/{task_id}/plot.png")
    assert plot.status_code == 200
    assert plot.content.startswith(b"\x89PNG")

    row.click()  # the task dialog shows the recorded path
    expect(browser_page.locator("#task-dialog")).to_be_visible()
    browser_page.wait_for_function(
        "() => { const img = document.getElementById('dialog-plot');"
        " return img.complete && img.naturalWidth > 0; }"
    )
    browser_page.keyboard.press("Escape")

    ARTIFACTS.mkdir(exist_ok=True)
    browser_page.screenshot(path=str(ARTIFACTS / "dashboard.png"))
    assert console.errors == []


def test_page_reconnects_and_reloads_after_a_server_restart(
    browser: Browser, tmp_path: Path
) -> None:
    """The stream drops when the server goes; the indicator says so, and once the server is
    back on the same address the page reconnects by itself and re-fetches the state."""
    data = tmp_path / "data"
    context = browser.new_context()
    try:
        page = context.new_page()
        with (tmp_path / "serve1.log").open("w") as log, running_server(data, stderr=log) as first:
            url = first.url
            page.goto(url + "/")
            page.wait_for_function("window.__parkfleet?.connection === 'live'")
            loads = page.evaluate("window.__parkfleet.loads")
            with httpx.Client(base_url=url, timeout=10) as http:
                task_id = http.post("/tasks", json={"goal": {"x": 1.0, "y": 1.0}}).json()["id"]
            assert first.stop() == 0
        page.wait_for_function("window.__parkfleet.connection !== 'live'")
        assert page.locator("#conn").get_attribute("data-state") in ("reconnecting", "offline")
        port = url.rsplit(":", 1)[1]
        with (
            (tmp_path / "serve2.log").open("w") as log,
            running_server(data, "--port", port, stderr=log) as second,
        ):
            assert second.url == url
            page.wait_for_function(
                "n => window.__parkfleet.connection === 'live' && window.__parkfleet.loads > n",
                arg=loads,
                timeout=30_000,
            )
            row = page.locator(f'#tasks-body tr[data-task-id="{task_id}"]')
            assert row.get_attribute("data-status") == "queued"
    finally:
        context.close()
