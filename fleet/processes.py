"""Child processes started by parkfleet commands, benches and tests.

Command lines for ``parkfleet`` sub-commands and one way to stop a child cleanly.
Children are started with :mod:`subprocess` (fork + exec at once), never by forking a
process that holds a Zenoh session (shared/DESIGN.md).
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
from collections.abc import Sequence
from typing import Any


def parkfleet_command(*args: str) -> list[str]:
    """``parkfleet ARGS`` run by this interpreter (works without the console script)."""
    return [sys.executable, "-m", "fleet.cli", *args]


def sim_command(
    endpoint: str,
    robots: int,
    *,
    time_scale: float = 1.0,
    spawn: str = "grid",
    seed: int | None = None,
    extra: Sequence[str] = (),
) -> list[str]:
    """``parkfleet sim`` with N robots connected to the router at ``endpoint``."""
    cmd = parkfleet_command(
        "sim",
        "--robots",
        str(robots),
        "--connect",
        endpoint,
        "--time-scale",
        str(time_scale),
        "--spawn",
        str(spawn),
    )
    if seed is not None:
        cmd += ["--seed", str(seed)]
    return [*cmd, *extra]


def terminate(process: subprocess.Popen[Any], timeout: float = 10.0) -> int | None:
    """SIGTERM (graceful), SIGKILL after ``timeout`` [s]; always reaps. Returns the exit code."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
    with contextlib.suppress(subprocess.TimeoutExpired):
        process.wait(timeout)
    return process.returncode
