"""Lockstep trace files: every robot's *true* pose and mode at every simulated tick.

Written by ``parkfleet sim --trace FILE`` (one record per lockstep tick, streamed, so memory
stays constant however long the run) and read by ``parkfleet bench fleet``, which measures
collisions and separations on poses of the same simulated instant, with no sample lost.

File format (version 1), little-endian::

    line 1   JSON header, then "\\n":
             {"format": "parkfleet-trace", "version": 1, "period_s": 0.02,
              "robots": ["b1", ...], "radii": [0.2, ...], "modes": ["idle", ...]}
    records  one per tick: float64 t [s, simulated],
             float64[N][3] true pose (x [m], y [m], theta [rad], world frame),
             uint8[N] mode (index into the header's "modes"; 255 = none yet)

A trailing partial record (a writer killed mid-write) is ignored by the reader.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np
import numpy.typing as npt

from fleet.core.types import FloatArray

FORMAT = "parkfleet-trace"
VERSION = 1
#: Mode code of a robot that has not ticked yet.
NO_MODE = 255

ModeArray = npt.NDArray[np.uint8]


@dataclass(frozen=True)
class TraceHeader:
    """What a trace holds: robot ids and body radii [m], tick period [s], mode names."""

    robots: tuple[str, ...]
    radii: tuple[float, ...]
    period_s: float
    modes: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.robots) != len(self.radii) or not self.robots:
            raise ValueError("a trace needs one radius per robot and at least one robot")
        if len(self.modes) >= NO_MODE:
            raise ValueError(f"at most {NO_MODE - 1} modes")

    @property
    def record_dtype(self) -> np.dtype[np.void]:
        n = len(self.robots)
        return np.dtype([("t", "<f8"), ("pose", "<f8", (n, 3)), ("mode", "u1", (n,))])

    def to_json(self) -> str:
        return json.dumps(
            {
                "format": FORMAT,
                "version": VERSION,
                "period_s": self.period_s,
                "robots": list(self.robots),
                "radii": list(self.radii),
                "modes": list(self.modes),
            }
        )

    @classmethod
    def from_json(cls, line: str, source: str = "trace") -> TraceHeader:
        try:
            data = json.loads(line)
            if data.get("format") != FORMAT or data.get("version") != VERSION:
                raise ValueError(f"not a {FORMAT} version {VERSION} file")
            return cls(
                robots=tuple(str(r) for r in data["robots"]),
                radii=tuple(float(r) for r in data["radii"]),
                period_s=float(data["period_s"]),
                modes=tuple(str(m) for m in data["modes"]),
            )
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"{source}: bad trace header: {exc}") from exc


class TraceWriter:
    """Streams one record per tick to ``path`` (buffered; flushed by :meth:`close`, e.g.
    through ``contextlib.closing``)."""

    def __init__(self, path: str | Path, header: TraceHeader) -> None:
        self.header = header
        self._codes = {name: k for k, name in enumerate(header.modes)}
        self._record = np.zeros(1, dtype=header.record_dtype)
        self._file: IO[bytes] | None = open(path, "wb")  # noqa: SIM115 (closed in close())
        self._file.write(header.to_json().encode() + b"\n")
        self.ticks = 0

    def mode_code(self, mode: str | None) -> int:
        """Code of a mode name (:data:`NO_MODE` for None); ValueError if unknown."""
        if mode is None:
            return NO_MODE
        try:
            return self._codes[mode]
        except KeyError:
            raise ValueError(f"unknown mode {mode!r}; header has {self.header.modes}") from None

    def write(
        self, t: float, poses: FloatArray | Sequence[Sequence[float]], modes: Sequence[int]
    ) -> None:
        """One tick: simulated time ``t`` [s], poses (N, 3), mode codes (N,)."""
        if self._file is None:
            raise ValueError("trace is closed")
        record = self._record[0]
        record["t"] = t
        record["pose"] = poses
        record["mode"] = modes
        self._file.write(self._record.tobytes())
        self.ticks += 1

    def close(self) -> None:
        """Flush and close (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None


@dataclass(frozen=True)
class TraceChunk:
    """Consecutive ticks: times (T,) [s], true poses (T, N, 3), mode codes (T, N)."""

    t: FloatArray
    poses: FloatArray
    modes: ModeArray


def read_header(path: str | Path) -> TraceHeader:
    with open(path, "rb") as f:
        return TraceHeader.from_json(f.readline().decode(), str(path))


def read_trace(path: str | Path, chunk_ticks: int = 4096) -> Iterator[TraceChunk]:
    """The records of a trace in chunks of at most ``chunk_ticks`` ticks (bounded memory)."""
    if chunk_ticks < 1:
        raise ValueError("chunk_ticks must be at least 1")
    with open(path, "rb") as f:
        header = TraceHeader.from_json(f.readline().decode(), str(path))
        dtype = header.record_dtype
        while True:
            data = f.read(dtype.itemsize * chunk_ticks)
            whole = len(data) // dtype.itemsize  # a partial record at the end is dropped
            if whole == 0:
                return
            records = np.frombuffer(data, dtype=dtype, count=whole)
            yield TraceChunk(
                t=records["t"].astype(np.float64),
                poses=records["pose"].astype(np.float64),
                modes=records["mode"].astype(np.uint8),
            )
            if whole < chunk_ticks:
                return
