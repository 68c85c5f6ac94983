"""The dashboard in a real browser: Debian's headless Chromium driven by Playwright.

One ``parkfleet serve`` (free ports, fresh data directory) and one ``parkfleet sim`` with two
robots serve the whole module; every test opens its own page. Without chromium or the
``playwright`` package the tests skip locally and fail under ``CI=true``. A screenshot of
the console goes to ``artifacts/dashboard.png``.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import httpx
import pytest

from fleet.io.processes import ServerProcess, running_server, sim_command, terminate

if TYPE_CHECKING:
    from playwright.sync_api import Browser, ConsoleMessage, Error, Page

pytestmark = pytest.mark.integration

CHROMIUM = "/usr/bin/chromium"
#: The network is closed here: without these Chromium hangs trying to reach Google.
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "artifacts"
TIME_SCALE = "5"
#: This module tests the page, not liveliness under CPU starvation: on a loaded two-core
#: box (chromium, server, 50 Hz sim) a robot can miss the default 1 s lease and be declared
#: lost, which fails its task. A longer lease and re-queueing keep that noise out.
FLEET_ENV = {"PARKFLEET_LEASE_MS": "5000", "PARKFLEET_ON_ROBOT_LOST": "requeue"}
TASK_TIMEOUT_MS = 90_000


def _chromium() -> str | None:
    if os.access(CHROMIUM, os.X_OK):
        return CHROMIUM
    return shutil.which("chromium")


def _missing() -> str | None:
    """Why the browser tests cannot run here, or None."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is missing: pip install -e '.[test]'"
    if _chromium() is None:
        return f"chromium is missing ({CHROMIUM}): apt-get install chromium"
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    reason = _missing()
    if reason is not None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"browser tests cannot run in CI: {reason}")
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=_chromium(), args=CHROMIUM_ARGS)
        try:
            yield launched
        finally:
            launched.close()


@dataclass
class Fleet:
    server: ServerProcess
    http: httpx.Client


@pytest.fixture(scope="module")
def fleet(browser: Browser, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    """``parkfleet serve`` plus ``parkfleet sim --robots 2`` connected to its router."""
    tmp = tmp_path_factory.mktemp("dashboard")
    with (
        (tmp / "serve.log").open("w") as serve_log,
        (tmp / "sim.log").open("w") as sim_log,
        running_server(tmp / "data", env=FLEET_ENV, stderr=serve_log) as server,
    ):
        sim = subprocess.Popen(
            sim_command(server.zenoh_endpoint, 2, time_scale=float(TIME_SCALE)),
            stdin=subprocess.DEVNULL,
            stdout=sim_log,
            env={**os.environ, **FLEET_ENV},
            stderr=sim_log,
        )
        try:
            with httpx.Client(base_url=server.url, timeout=10) as http:
                yield Fleet(server, http)
        finally:
            terminate(sim)


@dataclass
class Console:
    """Errors the page reported: console.error calls, failed loads, uncaught exceptions."""

    errors: list[str] = field(default_factory=list)

    def on_message(self, message: ConsoleMessage) -> None:
        if message.type == "error":
            self.errors.append(message.text)

    def on_page_error(self, error: Error) -> None:
        self.errors.append(f"uncaught: {error}")


@pytest.fixture
def page(browser: Browser, fleet: Fleet) -> Iterator[tuple[Page, Console]]:
    context = browser.new_context(viewport={"width": 1600, "height": 950})
    try:
        opened = context.new_page()
        console = Console()
        opened.on("console", console.on_message)
        opened.on("pageerror", console.on_page_error)
        opened.goto(fleet.server.url + "/")
        opened.wait_for_function("window.__parkfleet?.connection === 'live'")
        yield opened, console
    finally:
        context.close()


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
