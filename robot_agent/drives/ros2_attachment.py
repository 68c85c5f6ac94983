"""The rmw_zenoh attachment of every published message: sequence number, source time, GID.

rmw_zenoh (``docs/design.md`` "Publishers"; ``rmw_zenoh_cpp/src/detail/attachment_helpers.cpp``
``AttachmentData::serialize_to_zbytes``) writes it with Zenoh's own serialiser
(``zenoh::ext::Serializer``): int64 sequence number, int64 source timestamp [ns since the
Unix epoch], then the 16-byte publisher GID as a sequence (its length as a varint, 0x10,
then the bytes) -- 33 bytes, little-endian. A ROS subscription drops a sample without a
valid attachment, so this must be exact; ``zenoh.ext`` is the same serialiser for Python.

The GID only has to be unique per publisher (a ROS subscriber reports it in
``message_info``): rmw_zenoh hashes the entity's liveliness token with XXH3-128; here the
token is hashed with BLAKE2b-128 (stable per entity, no extra dependency).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import zenoh
from zenoh.ext import Int64, ZDeserializeError, z_deserialize, z_serialize

GID_BYTES = 16  # RMW_GID_STORAGE_SIZE in Jazzy; Humble's rmw_zenoh also sends 16
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


@dataclass(frozen=True)
class Attachment:
    """What rmw_zenoh attaches to a message: publisher sequence number (from 1), source
    timestamp [ns since the Unix epoch] and the publisher's 16-byte GID."""

    sequence_number: int
    source_timestamp_ns: int
    gid: bytes

    def __post_init__(self) -> None:
        if len(self.gid) != GID_BYTES:
            raise ValueError(f"a GID has {GID_BYTES} bytes, got {len(self.gid)}")
        for name in ("sequence_number", "source_timestamp_ns"):
            if not INT64_MIN <= getattr(self, name) <= INT64_MAX:
                raise ValueError(f"{name} does not fit an int64")


def encode_attachment(attachment: Attachment) -> bytes:
    """The 33 attachment bytes rmw_zenoh expects."""
    fields = (Int64(attachment.sequence_number), Int64(attachment.source_timestamp_ns))
    return bytes(z_serialize((*fields, attachment.gid)).to_bytes())


def decode_attachment(raw: bytes) -> Attachment:
    """Parse an rmw_zenoh attachment; ValueError if it is not one."""
    try:
        sequence, stamp, gid = z_deserialize(tuple[Int64, Int64, bytes], zenoh.ZBytes(raw))
        return Attachment(int(sequence), int(stamp), bytes(gid))
    except (ZDeserializeError, ValueError) as exc:
        raise ValueError(f"not an rmw_zenoh attachment ({len(raw)} bytes): {exc}") from exc


def entity_gid(token: str) -> bytes:
    """A stable 16-byte GID for the entity announced by liveliness ``token``."""
    return hashlib.blake2b(token.encode(), digest_size=GID_BYTES).digest()
