"""Real Zenoh over loopback: the config builder and session helpers."""

from __future__ import annotations

import threading

import pytest

from fleet.io.settings import Settings, load_settings
from fleet.io.transport import open_session


def test_client_reaches_router_and_pub_sub_works(client_settings: Settings) -> None:
    received: list[bytes] = []
    got = threading.Event()

    def on_sample(sample: object) -> None:
        received.append(sample.payload.to_bytes())  # type: ignore[attr-defined]
        got.set()

    with (
        open_session(client_settings, "client") as sub_session,
        open_session(client_settings, "client") as pub_session,
    ):
        sub = sub_session.declare_subscriber("parkfleet/test/ping", on_sample)
        try:
            pub = pub_session.declare_publisher("parkfleet/test/ping")
            for _ in range(50):  # the subscription needs a moment to propagate
                pub.put(b"hello")
                if got.wait(0.1):
                    break
        finally:
            sub.undeclare()
    assert received and received[0] == b"hello"


def test_client_without_router_fails_fast_with_a_clear_error() -> None:
    settings = load_settings(connect=["tcp/127.0.0.1:9"])
    with pytest.raises(ConnectionError, match="Is the fleet host"):
        open_session(settings, "client")
