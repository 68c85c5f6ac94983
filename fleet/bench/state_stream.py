"""A light stand-in for N idle robots on the wire: their states at R Hz and their
liveliness tokens, with no control loop (``python -m fleet.bench.state_stream``).

``bench zenoh --source stream`` uses it to load the fleet service at rates a simulated fleet
cannot reach on a small machine: each message is the agents' own ``RobotState`` JSON (a
template per robot, encoded once; only ``seq`` and ``stamp`` change), stamped with the wall
clock as it is published. Robots are spread over the period in slices, as independent
robots would be, not published in one burst. Runs until SIGINT/SIGTERM; prints one ready
line once every token is declared.
"""

from __future__ import annotations

import argparse
import math
import signal
import threading
import time

from fleet.core.wire import Keys, Pose, RobotState, encode
from fleet.io.settings import load_settings
from fleet.io.transport import open_session

#: Slices of the robots published one after another within each period.
SLICES = 10
_SEQ, _STAMP = 987654321, 1234.5  # sentinels replaced in the templates


def templates(keys: Keys, robots: int, prefix: str) -> list[tuple[str, str]]:
    """``(key, payload % (seq, stamp))`` per robot: idle robots on a 1.5 m grid."""
    side = math.ceil(math.sqrt(robots))
    out = []
    for i in range(robots):
        rid = f"{prefix}{i + 1}"
        pose = Pose(x=-9.0 + 1.5 * (i % side) % 18.0, y=-9.0 + 1.5 * (i // side) % 18.0)
        text = encode(RobotState(robot_id=rid, seq=_SEQ, stamp=_STAMP, pose=pose)).decode()
        text = text.replace("%", "%%").replace(str(_SEQ), "%d").replace(repr(_STAMP), "%r")
        out.append((keys.state(rid), text))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--connect", required=True)
    parser.add_argument("--robots", type=int, required=True)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--prefix", default="b")
    args = parser.parse_args(argv)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    settings = load_settings(connect=[args.connect])
    keys = Keys(settings.fleet_name)
    robots = templates(keys, args.robots, args.prefix)
    with open_session(settings, "client") as session:
        tokens = [
            session.liveliness().declare_token(keys.alive(f"{args.prefix}{i + 1}"))
            for i in range(len(robots))
        ]
        publishers = [(session.declare_publisher(key), text) for key, text in robots]
        print(f"stream: {args.robots} robots at {args.rate:g} Hz", flush=True)
        slot = 1.0 / args.rate / SLICES
        size = math.ceil(len(publishers) / SLICES)
        seq, due = 0, time.monotonic()
        while not stop.is_set():
            for s in range(SLICES):
                for publisher, text in publishers[s * size : (s + 1) * size]:
                    publisher.put((text % (seq, time.time())).encode())
                due += slot
                pause = due - time.monotonic()
                if pause > 0:
                    stop.wait(pause)
            seq += 1
        for publisher, _ in publishers:
            publisher.undeclare()  # type: ignore[no-untyped-call]
        for token in tokens:
            token.undeclare()  # type: ignore[no-untyped-call]
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
