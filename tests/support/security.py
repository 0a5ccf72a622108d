"""Frames signed by pymavlink and encrypted with `cryptography` directly, for the security tests (the
encoders and file writers are tests/support/builders.py's)."""

from __future__ import annotations

import hashlib
import struct

from pymavlink.dialects.v20 import all as v2

from tests.support.builders import EPOCH_2026 as EPOCH_2026
from tests.support.builders import command_long as command_long
from tests.support.builders import gcs_heartbeat
from tests.support.builders import radio_status as radio_status
from tests.support.builders import signer as signer
from tests.support.builders import write_raw as write_raw

PASSPHRASE = "correct horse battery staple"
SHA_KEY = hashlib.sha256(PASSPHRASE.encode()).digest()


def heartbeat(mav: v2.MAVLink) -> bytes:
    """A ground station's HEARTBEAT, base mode 192 (the security tests' sender is a GCS, 255/190)."""
    return gcs_heartbeat(mav, 192)


def fix_crc(frame: bytearray) -> bytearray:
    """Recompute the CRC of a v2 frame after its payload was changed (the signature is left as is)."""
    length = frame[1]
    msgid = frame[7] | frame[8] << 8 | frame[9] << 16
    crc = v2.x25crc(bytes(frame[1:10 + length]))
    crc.accumulate(bytes([v2.mavlink_map[msgid].crc_extra]))
    struct.pack_into("<H", frame, 10 + length, crc.crc)
    return frame


def statuses(rows: list[dict]) -> list[str | None]:
    return [r["signature"]["status"] if r["signature"] else None for r in rows]
