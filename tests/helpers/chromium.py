"""Headless Chromium for the browser tests (Debian's /usr/bin/chromium via Playwright).

The ``browser`` fixture lives in ``tests/integration/conftest.py``; without chromium or the
``playwright`` package browser tests skip locally and fail under ``CI=true``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import httpx

from fleet.io.processes import ServerProcess, running_server, sim_command, terminate

if TYPE_CHECKING:
    from playwright.sync_api import Browser, ConsoleMessage, Error, Page

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


def chromium_path() -> str | None:
    if os.access(CHROMIUM, os.X_OK):
        return CHROMIUM
    return shutil.which("chromium")


def missing() -> str | None:
    """Why the browser tests cannot run here, or None."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is missing: pip install -e '.[test]'"
    if chromium_path() is None:
        return f"chromium is missing ({CHROMIUM}): apt-get install chromium"
    return None


@dataclass
class Console:
    """Errors the page reported: console.error calls, failed loads, uncaught exceptions."""

    errors: list[str] = field(default_factory=list)

    def on_message(self, message: ConsoleMessage) -> None:
        if message.type == "error":
            self.errors.append(message.text)

    def on_page_error(self, error: Error) -> None:
        self.errors.append(f"uncaught: {error}")


@dataclass
class Fleet:
    """A live ``parkfleet serve`` with simulated robots, and an HTTP client to it."""

    server: ServerProcess
    http: httpx.Client


#: A loaded two-core box (chromium, server, 50 Hz sim) can make a robot miss the default 1 s
#: lease and be declared lost, which fails its task: the dashboard tests test the page, not
#: liveliness under CPU starvation, so they use a longer lease and re-queueing.
FLEET_ENV = {"PARKFLEET_LEASE_MS": "5000", "PARKFLEET_ON_ROBOT_LOST": "requeue"}


@contextmanager
def served_fleet(tmp: Path, robots: int, time_scale: float, *serve_args: str) -> Iterator[Fleet]:
    """``parkfleet serve SERVE_ARGS`` plus ``parkfleet sim --robots N`` on its router (logs in
    ``tmp``); both stopped on exit."""
    with (
        (tmp / "serve.log").open("w") as serve_log,
        (tmp / "sim.log").open("w") as sim_log,
        running_server(tmp / "data", *serve_args, env=FLEET_ENV, stderr=serve_log) as server,
    ):
        sim = subprocess.Popen(
            sim_command(server.zenoh_endpoint, robots, time_scale=time_scale),
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


@contextmanager
def console_page(
    browser: Browser, url: str, width: int = 1600, height: int = 950
) -> Iterator[tuple[Page, Console]]:
    """A fresh browser context on the dashboard at ``url``, once its event stream is live;
    the Console collects the page's errors."""
    context = browser.new_context(viewport={"width": width, "height": height})
    try:
        page = context.new_page()
        console = Console()
        page.on("console", console.on_message)
        page.on("pageerror", console.on_page_error)
        page.goto(url + "/")
        page.wait_for_function("window.__parkfleet?.connection === 'live'")
        yield page, console
    finally:
        context.close()
