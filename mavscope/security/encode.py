"""Build MAVLink v2 frames with encrypted payloads and signatures (for captures, tests and tools).

The order is SecureMAV's: encrypt the payload, then compute the CRC (with the message's CRC_EXTRA)
and the signature over the frame as sent.
"""

from __future__ import annotations

import struct

from mavscope.mavlink.framing import mcrf4xx
from mavscope.security.ciphers import FixedKeystream, gcm_seal, gcm_session_key
from mavscope.security.keys import SigningKey

STX_V2 = 0xFD


def trim(payload: bytes) -> bytes:
    """MAVLink 2 payload truncation: trailing zero bytes dropped, at least one byte kept."""
    out = payload.rstrip(b"\x00")
    return out if out else payload[:1]


def header_v2(length: int, incompat: int, seq: int, sysid: int, compid: int, msgid: int, compat: int = 0) -> bytes:
    return struct.pack("<BBBBBBBHB", STX_V2, length, incompat, compat, seq, sysid, compid, msgid & 0xFFFF, msgid >> 16)


def finish_frame(header: bytes, payload: bytes, crc_extra: int, signing: SigningKey | None = None,
                 link_id: int = 0, timestamp: int = 0) -> bytes:
    """header || payload || CRC, then the signature block when `signing` is given (header must say so)."""
    crc = mcrf4xx(bytes([crc_extra]), mcrf4xx(header[1:] + payload))
    frame = header + payload + struct.pack("<H", crc)
    if signing is not None:
        frame += bytes([link_id]) + timestamp.to_bytes(6, "little")
        frame += signing.mac(frame)
    return frame


def encode_frame(msgid: int, payload: bytes, crc_extra: int, *, seq: int = 0, sysid: int = 1, compid: int = 1,
                 method: int = 0, scheme: str | None = None, key: bytes = b"", iv: bytes = b"\x00" * 16,
                 session_id: int = 0, counter: int = 0, signing: SigningKey | None = None, link_id: int = 0,
                 timestamp: int = 0) -> bytes:
    """A v2 frame of `payload` (plaintext, trimmed here), encrypted with `scheme` under incompat
    method `method` when given, signed when `signing` is given.

    scheme: "xor" (key bytes repeated), "aes-128-ctr" (key 16 bytes, counter restarted at `iv`),
    "aes-gcm" (key = master key; `session_id`/`counter` form the nonce: never reuse them under a key).
    """
    plain = trim(payload)
    iflags = (method << 5) | (1 if signing is not None else 0)
    if not method:
        body = plain
    elif scheme == "xor":
        body = FixedKeystream.xor(key).apply(plain)
    elif scheme == "aes-128-ctr":
        body = FixedKeystream.aes_ctr(key, iv).apply(plain)
    elif scheme == "aes-gcm":
        header = header_v2(len(plain) + 28, iflags, seq, sysid, compid, msgid)
        body = gcm_seal(gcm_session_key(key, session_id), session_id, counter, header, plain)
    else:
        raise ValueError(f"unknown scheme {scheme!r}")
    header = header_v2(len(body), iflags, seq, sysid, compid, msgid)
    return finish_frame(header, body, crc_extra, signing, link_id, timestamp)
