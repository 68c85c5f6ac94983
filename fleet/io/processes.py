"""Child processes started by parkfleet commands, benches and tests.

Command lines for ``parkfleet`` sub-commands, one way to stop a child cleanly, and a live
``parkfleet serve`` child (:func:`running_server`): it binds free ports (API ``--port 0``,
Zenoh ``tcp/127.0.0.1:0``) and prints one ready line with the real addresses, parsed here.
Children are started with :mod:`subprocess` (fork + exec at once), never by forking a
process that holds a Zenoh session (shared/DESIGN.md).
"""

from __future__ import annotations

import contextlib
import os
import queue
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from fleet.io.transport import tcp_endpoint


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


READY = re.compile(r"^parkfleet serve: API on (?P<url>\S+) .*Zenoh router on (?P<zenoh>.*)$")


@dataclass
class ServerProcess:
    process: subprocess.Popen[str]
    url: str
    zenoh: list[str]

    @property
    def zenoh_endpoint(self) -> str:
        """A TCP endpoint of the server's router (loopback preferred)."""
        return tcp_endpoint(self.zenoh)

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM (graceful), SIGKILL after ``timeout``; returns the exit code."""
        code = terminate(self.process, timeout)
        assert code is not None
        return code


def serve_command(data_dir: Path, *extra: str) -> list[str]:
    return parkfleet_command(
        "serve",
        "--port",
        "0",
        "--zenoh-listen",
        "tcp/127.0.0.1:0",
        "--data-dir",
        str(data_dir),
        *extra,
    )


def _pump(stream: IO[str], lines: queue.Queue[str | None]) -> None:
    for line in stream:
        lines.put(line.rstrip("\n"))
    lines.put(None)


@contextmanager
def running_server(
    data_dir: Path,
    *extra: str,
    env: Mapping[str, str] | None = None,
    stderr: IO[str] | int | None = None,
    timeout: float = 120.0,
) -> Iterator[ServerProcess]:
    """A live ``parkfleet serve`` child; stopped (and reaped) on exit, whatever happens.
    ``timeout`` [s] bounds a hung start, not a slow one: imports and compiled code take
    seconds alone and far longer on a loaded machine."""
    process = subprocess.Popen(
        serve_command(data_dir, *extra),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        env={**os.environ, **(env or {})},
    )
    server: ServerProcess | None = None
    assert process.stdout is not None
    lines: queue.Queue[str | None] = queue.Queue()
    pump = threading.Thread(target=_pump, args=(process.stdout, lines), daemon=True)
    pump.start()
    try:
        deadline = time.monotonic() + timeout
        while server is None:
            try:
                line = lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise TimeoutError(f"parkfleet serve not ready after {timeout:.0f} s") from None
            if line is None:
                raise RuntimeError(f"parkfleet serve exited early with {process.wait()}")
            match = READY.match(line)
            if match:
                server = ServerProcess(process, match["url"], match["zenoh"].split())
        yield server
    finally:
        if server is not None:
            server.stop()
        elif process.poll() is None:
            process.kill()
        process.wait()
        pump.join(5.0)  # EOF once the child is gone
        process.stdout.close()
