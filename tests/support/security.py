"""Frames signed by pymavlink and encrypted with `cryptography` directly, for the security tests."""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

from pymavlink.dialects.v20 import all as v2

PASSPHRASE = "correct horse battery staple"
SHA_KEY = hashlib.sha256(PASSPHRASE.encode()).digest()
EPOCH_2026 = (1_773_482_400 - 1_420_070_400) * 100_000  # signature timestamp of 2026-03-14T10:00:00Z


def signer(key: bytes | None, sysid: int = 255, compid: int = 190, link_id: int = 1,
           timestamp: int = EPOCH_2026) -> v2.MAVLink:
    """A pymavlink encoder that signs with `key` (None: unsigned), explicit timestamps."""
    mav = v2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.link_id = link_id
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = timestamp
    return mav


def heartbeat(mav: v2.MAVLink) -> bytes:
    return bytes(mav.heartbeat_encode(6, 8, 192, 0, 4, 3).pack(mav))


def command_long(mav: v2.MAVLink, command: int = 20) -> bytes:
    return bytes(mav.command_long_encode(1, 1, command, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav))


def radio_status(mav: v2.MAVLink) -> bytes:
    return bytes(mav.radio_status_encode(200, 190, 100, 50, 40, 0, 0).pack(mav))


def fix_crc(frame: bytearray) -> bytearray:
    """Recompute the CRC of a v2 frame after its payload was changed (the signature is left as is)."""
    length = frame[1]
    msgid = frame[7] | frame[8] << 8 | frame[9] << 16
    crc = v2.x25crc(bytes(frame[1:10 + length]))
    crc.accumulate(bytes([v2.mavlink_map[msgid].crc_extra]))
    struct.pack_into("<H", frame, 10 + length, crc.crc)
    return frame


def write_raw(tmp: Path, frames: list[bytes], name: str = "cap.raw") -> str:
    path = tmp / name
    path.write_bytes(b"".join(frames))
    return str(path)


def statuses(rows: list[dict]) -> list[str | None]:
    return [r["signature"]["status"] if r["signature"] else None for r in rows]
