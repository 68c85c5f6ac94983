"""A light stand-in for N idle robots on the wire: their two state streams and their
liveliness tokens, with no control loop (``python -m fleet.bench.state_stream``).

``bench zenoh --source stream`` uses it to load the fleet service at rates a simulated fleet
cannot reach on a small machine: each robot's compact ``RobotState`` (its
:class:`~fleet.core.wire.StateFrame`, only ``seq`` and ``stamp`` changing, stamped with the
wall clock as it is published) goes on its cell's peer key at R Hz and on its fleet-rate key
every ``R / fleet_rate_hz``-th tick, as the agents' :class:`StateStreams` do. Robots stand
where ``--spawn`` (a JSON list of ``{id, x, y}``) puts them and are spread over the period
in slices, as independent robots would be, not published in one burst. Runs until
SIGINT/SIGTERM; prints one ready line once every token is declared.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import threading
import time
from pathlib import Path

import msgspec

from fleet.core.wire import COMPACT_STATE_V1, Keys, StateFrame
from fleet.io.settings import load_settings
from fleet.io.transport import open_session

#: Slices of the robots published one after another within each period.
SLICES = 10


def frames(keys: Keys, spawn: list[dict[str, float | str]]) -> list[tuple[str, str, StateFrame]]:
    """``(peer key, fleet key, frame)`` per robot of ``spawn``, idle where it stands."""
    out = []
    for entry in spawn:
        rid, x, y = str(entry["id"]), float(entry["x"]), float(entry["y"])
        frame = StateFrame(rid, 0, 0.0, x, y, 0.0)
        out.append((keys.peer_state(rid, keys.cell(x, y)), keys.state(rid), frame))
    return out


def payload(frame: StateFrame, seq: int, stamp: float) -> bytes:
    """The compact state of ``frame`` with ``seq`` and ``stamp`` [s since epoch]."""
    return bytes([COMPACT_STATE_V1]) + msgspec.msgpack.encode(
        msgspec.structs.replace(frame, seq=seq, stamp=stamp)
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--connect", required=True)
    parser.add_argument("--spawn", type=Path, required=True)
    parser.add_argument("--rate", type=float, default=50.0)
    args = parser.parse_args(argv)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    settings = load_settings(connect=[args.connect])
    keys = settings.keys()
    robots = frames(keys, json.loads(args.spawn.read_text()))
    every = max(1, round(args.rate / settings.fleet_rate_hz))  # ticks per fleet-rate state
    with open_session(settings, "client") as session:
        tokens = [session.liveliness().declare_token(keys.alive(f.robot_id)) for *_, f in robots]
        publishers = [
            (session.declare_publisher(peer), session.declare_publisher(fleet), frame)
            for peer, fleet, frame in robots
        ]
        print(f"stream: {len(robots)} robots at {args.rate:g} Hz", flush=True)
        slot = 1.0 / args.rate / SLICES
        size = math.ceil(len(publishers) / SLICES)
        seq, due = 0, time.monotonic()
        while not stop.is_set():
            for s in range(SLICES):
                for k, (peer, fleet, frame) in enumerate(publishers[s * size : (s + 1) * size]):
                    data = payload(frame, seq, time.time())
                    peer.put(data)
                    if (seq + k) % every == 0:  # robots' fleet-rate states spread over ticks
                        fleet.put(data)
                due += slot
                pause = due - time.monotonic()
                if pause > 0:
                    stop.wait(pause)
            seq += 1
        for peer, fleet, _ in publishers:
            peer.undeclare()  # type: ignore[no-untyped-call]
            fleet.undeclare()  # type: ignore[no-untyped-call]
        for token in tokens:
            token.undeclare()  # type: ignore[no-untyped-call]
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
