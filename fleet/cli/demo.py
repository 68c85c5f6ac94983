"""``parkfleet demo``: the API and fleet service plus N simulated robots on this machine.

The robots run in a ``parkfleet sim`` subprocess started only once the Zenoh router
listens, connected to the endpoint the router really listens on, and stopped before the
router closes. ``subprocess`` (fork + exec) is safe after a Zenoh session is open;
``multiprocessing`` fork is not.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import shlex
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleet.cli.options import add_server, add_spawn, add_time_scale
from fleet.cli.serve import server_settings
from fleet.core.tasks import FleetEvent, RobotEvent, RobotStatus, TaskEvent, TaskStatus
from fleet.io import processes
from fleet.io.settings import Settings
from fleet.io.transport import tcp_endpoint

if TYPE_CHECKING:
    from api import server


@dataclass(frozen=True)
class DemoOptions:
    robots: int = 4
    time_scale: float = 1.0
    spawn: str = "random"
    seed: int | None = None


def sim_command(endpoint: str, options: DemoOptions) -> list[str]:
    return processes.sim_command(
        endpoint,
        options.robots,
        time_scale=options.time_scale,
        spawn=options.spawn,
        seed=options.seed,
    )


def curl_examples(url: str, token: bool, site: bool = False, zenoh: str = "") -> list[str]:
    auth = " -H 'Authorization: Bearer $PARKFLEET_API_TOKEN'" if token else ""
    body = json.dumps({"goal": {"x": 3.0, "y": 2.0, "theta": 1.57}})
    post = f"curl -s -X POST {url}/tasks -H 'Content-Type: application/json'{auth}"
    bays = [f"{post} -d '{json.dumps({'bay_group': 'charging'})}'   # a free charging bay"]
    stop = [f"parkfleet estop --connect {zenoh}   # stop every robot (--release to undo)"]
    return [
        f"{post} -d '{body}'",
        *(bays if site else []),
        f"curl -s {url}/tasks/<id>        # watch it reach succeeded",
        f"curl -s {url}/robots",
        f"curl -sN {url}/events           # live robot states and task changes",
        *(stop if zenoh else []),
    ]


class _Progress:
    """Prints task transitions and robots joining or getting lost (service threads)."""

    def __init__(self) -> None:
        self._robots: dict[str, RobotStatus] = {}
        self._tasks: dict[str, TaskStatus] = {}

    def __call__(self, event: FleetEvent) -> None:
        if isinstance(event, TaskEvent):
            task = event.task
            if self._tasks.get(task.id) == task.status:
                return
            self._tasks[task.id] = task.status
            extra = "".join(
                f" {name}={value}"
                for name, value in (
                    ("robot", task.robot_id),
                    ("law", task.law),
                    ("reason", task.reason),
                )
                if value is not None
            )
            goal = task.request.goal
            print(
                f"[demo] task {task.id}: {task.status.value} (goal {goal.x:g}, {goal.y:g}){extra}",
                flush=True,
            )
        if isinstance(event, RobotEvent):
            robot = event.robot
            before = self._robots.get(robot.robot_id)
            self._robots[robot.robot_id] = robot.status
            if before is None:
                p = robot.pose
                print(f"[demo] robot {robot.robot_id} joined at ({p.x:.2f}, {p.y:.2f})", flush=True)
            elif (before == RobotStatus.LOST) != (robot.status == RobotStatus.LOST):
                print(f"[demo] robot {robot.robot_id}: {robot.status.value}", flush=True)


async def serve_demo(settings: Settings, options: DemoOptions) -> int:
    from api import server  # FastAPI loads only when a command needs it

    sim: subprocess.Popen[bytes] | None = None
    unsubscribe: list[Callable[[], None]] = []

    async def on_ready(running: server.Running) -> None:
        nonlocal sim
        endpoint = tcp_endpoint(running.zenoh)
        unsubscribe.append(running.app.state.service.add_listener(_Progress()))
        cmd = sim_command(endpoint, options)
        print(
            f"[demo] starting {options.robots} simulated robots: {shlex.join(cmd[1:])}", flush=True
        )
        sim = subprocess.Popen(cmd, stdin=subprocess.DEVNULL)
        lines = [
            "",
            f"parkfleet demo: API on {running.url}  (docs: {running.url}/docs)",
            f"                Zenoh router on {', '.join(running.zenoh)}",
            f"                data in {settings.db_path}",
            "Submit a parking task and watch it:",
            *(
                f"  {line}"
                for line in curl_examples(
                    running.url, settings.api_token is not None, settings.site is not None, endpoint
                )
            ),
            "Ctrl-C stops the demo.",
            "",
        ]
        print("\n".join(lines), flush=True)

    async def stop_sim() -> None:
        for stop in unsubscribe:
            stop()
        unsubscribe.clear()
        if sim is not None:
            await asyncio.to_thread(processes.terminate, sim, 5.0)

    try:
        return await server.serve(settings, on_ready=on_ready, on_shutdown=stop_sim)
    finally:
        if sim is not None:
            processes.terminate(sim, timeout=5.0)
            if sim.returncode not in (0, -2, -15, 130):
                print(f"[demo] the simulator exited with {sim.returncode}", file=sys.stderr)


def register(commands: Any, bench: Any) -> None:
    d = commands.add_parser(
        "demo",
        help="serve plus N simulated robots on this machine; prints a curl example",
        description="Runs `parkfleet serve` and a `parkfleet sim` subprocess with N robots "
        "connected to its Zenoh router, then prints the URL and a curl example.",
    )
    d.add_argument("--robots", type=int, default=4, help="number of simulated robots (default 4)")
    add_time_scale(d)
    add_spawn(d, default="grid")
    add_server(d, default_data="./var/demo", default_site="the example car park")
    d.set_defaults(func=run)


#: The example car park (``fleet/io/sites/carpark.toml``) the demo loads unless told otherwise.
EXAMPLE_SITE = Path(__file__).resolve().parents[1] / "io" / "sites" / "carpark.toml"


def run(args: argparse.Namespace) -> int:
    if args.robots < 1:
        raise ValueError("--robots must be at least 1")
    if args.site is None and not os.environ.get("PARKFLEET_SITE_FILE"):
        args.site = str(EXAMPLE_SITE)
    settings = server_settings(args)
    if args.data_dir is None and "data_dir" not in settings.model_fields_set:
        settings = settings.model_copy(update={"data_dir": Path("var/demo")})
    options = DemoOptions(
        robots=args.robots, time_scale=args.time_scale, spawn=args.spawn, seed=args.seed
    )
    from api.server import run_loop

    return run_loop(serve_demo(settings, options))
