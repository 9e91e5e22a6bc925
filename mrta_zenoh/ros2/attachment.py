"""The attachment rmw_zenoh requires on every sample (rmw_zenoh_cpp Jazzy ≥ 0.2.4, Humble ≥ 0.1.2,
Kilted, Rolling ≥ 0.6.0 — docs/ros2.md): 33 bytes,
little-endian —

    i64 sequence number (per publisher, from 1)
    i64 source timestamp (ns)
    u8  GID length (16)
    16  publisher GID

A sample without one is dropped by rmw_zenoh subscribers, silently (rmw_zenoh #569). An early
Jazzy layout (a 77-byte key/value map, #637) is refused here with a message saying so.
"""

from __future__ import annotations

import os
import struct
from typing import NamedTuple

GID_SIZE = 16
SIZE = 8 + 8 + 1 + GID_SIZE
_LAYOUT = struct.Struct("<qqB16s")


class AttachmentError(ValueError):
    pass


class Attachment(NamedTuple):
    sequence: int
    timestamp_ns: int
    gid: bytes

    def pack(self) -> bytes:
        return _LAYOUT.pack(self.sequence, self.timestamp_ns, GID_SIZE, self.gid)

    @classmethod
    def unpack(cls, data: bytes | None) -> "Attachment":
        if data is None:
            raise AttachmentError("no attachment (rmw_zenoh drops such samples)")
        if len(data) != SIZE:
            hint = (" (the early-Jazzy key/value layout of rmw_zenoh before Jazzy 0.2.4, Humble "
                    "0.1.2, Rolling 0.6.0: upgrade the robot's rmw_zenoh)"
                    if len(data) == 77 else "")
            raise AttachmentError(f"attachment of {len(data)} bytes, expected {SIZE}{hint}")
        seq, ts, n, gid = _LAYOUT.unpack(data)
        if n != GID_SIZE:
            raise AttachmentError(f"GID length byte is {n}, expected {GID_SIZE}")
        return cls(seq, ts, gid)


class Stamper:
    """One publisher's attachments: its GID (the one rmw_zenoh derives from the publisher's
    token, names.gid_of; drawn at random if none is given), sequence numbers from 1."""

    def __init__(self, gid: bytes | None = None):
        self.gid = gid if gid is not None else os.urandom(GID_SIZE)
        if len(self.gid) != GID_SIZE:
            raise AttachmentError(f"a GID has {GID_SIZE} bytes, got {len(self.gid)}")
        self.sequence = 0

    def next(self, timestamp_ns: int) -> bytes:
        self.sequence += 1
        return Attachment(self.sequence, timestamp_ns, self.gid).pack()
