"""What a process costs and holds, read from Linux ``/proc``: CPU time, resident memory,
open file descriptors, threads. Shared by the benches (one reader, not one per bench)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path


def cpu_seconds(pid: int) -> float:
    """utime + stime [s] of a process."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@dataclass(frozen=True)
class Holdings:
    """What a process holds at one moment."""

    rss_bytes: int
    open_fds: int
    threads: int


def holdings(pid: int) -> Holdings:
    """Resident memory [bytes], open file descriptors and threads of a process now."""
    status = dict(
        line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines()
    )
    rss_kb = int(status["VmRSS"].split()[0])
    return Holdings(
        rss_bytes=rss_kb * 1024,
        open_fds=len(os.listdir(f"/proc/{pid}/fd")),
        threads=int(status["Threads"]),
    )
