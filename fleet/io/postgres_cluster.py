"""A throwaway PostgreSQL cluster in a temporary directory (tests and ``bench failover``).

:class:`TempCluster` runs Debian's (or any) PostgreSQL binaries: ``initdb`` into a fresh
directory, ``pg_ctl start`` on a free loopback port (trust authentication, listening on
127.0.0.1 only, ``fsync=off``: a throwaway cluster need not survive a power loss, but
commits reach the OS, so it survives its server being killed), and on
close ``pg_ctl stop -m immediate`` and the directory removed.

``initdb`` refuses to run as root: as root the cluster runs as an unprivileged user
(``nobody`` unless told), through ``runuser``, in a directory owned by that user. The
binaries are found from ``PARKFLEET_PG_BIN``, ``pg_config --bindir``, or the newest
``/usr/lib/postgresql/<version>/bin`` (Debian); :func:`find_bindir` says why when none is.
"""

from __future__ import annotations

import contextlib
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path
from types import TracebackType

_DEBIAN = Path("/usr/lib/postgresql")


def find_bindir() -> Path | str:
    """The directory of ``initdb`` and ``pg_ctl``, or a sentence saying why there is none."""
    given = os.environ.get("PARKFLEET_PG_BIN")
    candidates: list[Path] = [Path(given)] if given else []
    pg_config = shutil.which("pg_config")
    if pg_config:
        out = subprocess.run([pg_config, "--bindir"], capture_output=True, text=True, check=False)
        candidates.append(Path(out.stdout.strip()))
    if _DEBIAN.is_dir():
        versions = sorted(
            (p for p in _DEBIAN.iterdir() if p.name.isdigit()), key=lambda p: int(p.name)
        )
        candidates += [p / "bin" for p in reversed(versions)]
    for bindir in candidates:
        if (bindir / "initdb").is_file() and (bindir / "pg_ctl").is_file():
            return bindir
    return (
        "no PostgreSQL server binaries (initdb, pg_ctl) found: install Debian's postgresql "
        "package or set PARKFLEET_PG_BIN"
    )


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class TempCluster:
    """A PostgreSQL cluster of its own (module docstring); ``dsn`` once started."""

    def __init__(self, bindir: Path | None = None, user: str = "nobody") -> None:
        found = bindir if bindir is not None else find_bindir()
        if isinstance(found, str):
            raise FileNotFoundError(found)
        self.bindir = found
        self.as_user = user if os.geteuid() == 0 else None
        self.root = Path(tempfile.mkdtemp(prefix="parkfleet-pg-"))
        self.data = self.root / "data"
        self.port = 0
        self.dsn = ""
        self._started = False

    def _run(self, *args: str) -> None:
        cmd = [str(self.bindir / args[0]), *args[1:]]
        if self.as_user is not None:
            cmd = ["runuser", "-u", self.as_user, "--", *cmd]
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"{args[0]} failed ({done.returncode}): {done.stderr.strip()}")

    def start(self) -> TempCluster:
        """initdb, then start on a free port; waits until it accepts connections."""
        try:
            if self.as_user is not None:
                pw = pwd.getpwnam(self.as_user)
                os.chown(self.root, pw.pw_uid, pw.pw_gid)
            self._run("initdb", "-D", str(self.data), "-A", "trust", "-U", "postgres", "-E",
                      "UTF8", "--no-sync")  # fmt: skip
            self.port = _free_port()
            self.start_server()
        except BaseException:
            self.close()
            raise
        self.dsn = f"postgresql://postgres@127.0.0.1:{self.port}/postgres"
        return self

    def start_server(self) -> None:
        """Start the server (again) on its port; waits until it accepts connections."""
        options = (
            f"-c listen_addresses=127.0.0.1 -c port={self.port} "
            f"-c unix_socket_directories={self.root} -c fsync=off "
            "-c full_page_writes=off -c max_connections=100"
        )
        log = self.root / "server.log"
        self._run("pg_ctl", "-D", str(self.data), "-l", str(log), "-o", options, "-w",
                  "-t", "60", "start")  # fmt: skip
        self._started = True

    def kill_server(self) -> None:
        """Stop the server the hard way (``-m immediate``: as if it crashed)."""
        self._started = False
        self._run("pg_ctl", "-D", str(self.data), "-m", "immediate", "-w", "stop")

    def close(self) -> None:
        """Stop the server (immediately) and remove its directory; idempotent."""
        if self._started:
            with contextlib.suppress(RuntimeError):  # already gone: the directory still goes
                self.kill_server()
        shutil.rmtree(self.root, ignore_errors=True)

    def __enter__(self) -> TempCluster:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
