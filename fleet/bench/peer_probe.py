"""A few robots' view of the peer stream (``python -m fleet.bench.peer_probe``), for
``bench zenoh``: what each ``--robot ID`` (its position from ``--spawn``) receives from
its peers.

Each probe robot has a session of its own (so every simulated robot is remote to it) and
subscribes, as an agent's feed does, to the peer stream of the 3 x 3 block of cells around
its position (:func:`fleet.core.wire.cells_around` with reach = cell size). It decodes
every state (the agents' decoder) and counts, over a window: states a second, distinct
peers heard, the age of each state (wall clock - stamp), and -- from ``--spawn`` (the
robots' positions, idle) -- the peers within the peer radius that were never heard.

Protocol on stdin/stdout: one ``ready`` line once subscribed; ``go`` starts the window,
``stop`` ends it and prints one JSON object ``{"probes": [...]}``; then it exits.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

from fleet.bench.metrics import percentile
from fleet.core.wire import Keys, RobotState, cells_around
from fleet.io.decoder import Decoder
from fleet.io.settings import load_settings
from fleet.io.transport import open_session


class Probe:
    """One robot's subscriptions and what arrived on them."""

    def __init__(self, session: Any, keys: Keys, robot_id: str, x: float, y: float) -> None:
        self.robot_id, self.x, self.y = robot_id, x, y
        self.decoder = Decoder("probe")
        self.recording = False
        self.ages: list[float] = []  # list.append is atomic
        self.heard: Counter[str] = Counter()
        self.cells = sorted(cells_around(x, y, keys.cell_m, keys.cell_m))
        self.subscribers = [
            session.declare_subscriber(keys.cell_states(cell), self._on) for cell in self.cells
        ]

    def _on(self, sample: Any) -> None:
        if not self.recording:
            return
        state = self.decoder.decode(RobotState, sample.payload.to_bytes())
        if state is not None and state.robot_id != self.robot_id:  # its own: not a peer
            self.ages.append(time.time() - state.stamp)
            self.heard[state.robot_id] += 1

    def report(self, window: float, near: set[str]) -> dict[str, Any]:
        ages_ms = [1e3 * a for a in self.ages]
        return {
            "robot": self.robot_id,
            "at": [self.x, self.y],
            "cells": len(self.cells),
            "peer_states_per_s": len(self.ages) / window,
            "peers_heard": len(self.heard),
            "peers_within_radius": len(near),
            "missed_within_radius": sorted(near - set(self.heard)),
            "age_p50_ms": percentile(ages_ms, 50),
            "age_p99_ms": percentile(ages_ms, 99),
            "dropped": self.decoder.dropped_total,
        }

    def close(self) -> None:
        for subscriber in self.subscribers:
            subscriber.undeclare()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--connect", required=True)
    parser.add_argument("--robot", action="append", required=True, help="a probe robot's id")
    parser.add_argument("--spawn", type=Path, required=True, help="the robots' spawn JSON")
    args = parser.parse_args(argv)
    settings = load_settings(connect=[args.connect])
    keys = settings.keys()
    spawn = json.loads(args.spawn.read_text())
    robots = {str(r["id"]): (float(r["x"]), float(r["y"])) for r in spawn}
    radius = settings.avoidance.peer_radius
    sessions = [open_session(settings, "client") for _ in args.robot]
    probes: list[Probe] = []
    try:
        for session, rid in zip(sessions, args.robot, strict=True):
            probes.append(Probe(session, keys, rid, *robots[rid]))
        print("ready", flush=True)
        sys.stdin.readline()  # go
        t0 = time.monotonic()
        for probe in probes:
            probe.recording = True
        sys.stdin.readline()  # stop
        for probe in probes:
            probe.recording = False
        window = time.monotonic() - t0
        rows = []
        for probe in probes:
            near = {
                rid
                for rid, (rx, ry) in robots.items()
                if rid != probe.robot_id and math.hypot(rx - probe.x, ry - probe.y) <= radius
            }
            rows.append(probe.report(window, near))
        print(json.dumps({"probes": rows}), flush=True)
    finally:
        for probe in probes:
            probe.close()
        for session in sessions:
            session.close()  # type: ignore[no-untyped-call]
    return 0


if __name__ == "__main__":
    threading.current_thread().name = "peer-probe"
    raise SystemExit(main())
