"""The rmw_zenoh attachment: exact bytes, round trip, and zenoh-ros2-sdk's reading of it."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st
from zenoh_ros2_sdk.attachment import Attachment as SdkAttachment

from robot_agent.drives.ros2_attachment import (
    Attachment,
    decode_attachment,
    encode_attachment,
    entity_gid,
)

int64 = st.integers(-(2**63), 2**63 - 1)
gids = st.binary(min_size=16, max_size=16)


def test_exact_bytes_of_design_md_layout() -> None:
    """design.md: int64 sequence number, int64 timestamp [ns], GID length (16), 16 GID bytes."""
    gid = bytes(range(16))
    raw = encode_attachment(Attachment(7, 1_700_000_000_123_456_789, gid))
    assert raw == struct.pack("<qqB", 7, 1_700_000_000_123_456_789, 16) + gid
    assert len(raw) == 33


@given(int64, int64, gids)
def test_round_trip_and_the_sdk_reads_the_same_fields(seq: int, stamp: int, gid: bytes) -> None:
    raw = encode_attachment(Attachment(seq, stamp, gid))
    assert decode_attachment(raw) == Attachment(seq, stamp, gid)
    if seq >= 0 and stamp >= 0:  # the SDK reads them as unsigned
        sdk = SdkAttachment.from_bytes(raw)
        assert (sdk.sequence_id, sdk.timestamp_ns, sdk.gid) == (seq, stamp, gid)


@pytest.mark.parametrize("junk", [b"", b"\x01\x02", bytes(16), bytes(17) + b"\x20"])
def test_junk_is_a_value_error(junk: bytes) -> None:
    with pytest.raises(ValueError, match="not an rmw_zenoh attachment"):
        decode_attachment(junk)


def test_bad_fields_are_refused() -> None:
    with pytest.raises(ValueError, match="16 bytes"):
        Attachment(1, 1, bytes(24))
    with pytest.raises(ValueError, match="int64"):
        Attachment(2**63, 1, bytes(16))


def test_gids_are_stable_per_token_and_differ_between_tokens() -> None:
    assert entity_gid("@ros2_lv/0/a/0/1/MP") == entity_gid("@ros2_lv/0/a/0/1/MP")
    assert entity_gid("@ros2_lv/0/a/0/1/MP") != entity_gid("@ros2_lv/0/a/0/2/MP")
    assert len(entity_gid("x")) == 16
