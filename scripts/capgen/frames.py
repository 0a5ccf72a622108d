"""MAVLink frames as the generator makes them: pymavlink encodes, signs and sequences the ordinary ones
(`Endpoint`), a few are built by hand for what pymavlink will not produce, and every frame carries what
a decoder must find in it, so that expected.json is computed from what was generated, not by decoding."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import pymavlink.dialects.v20.common as mav2

from .constants import SIGNING_EPOCH_US, SIGNING_KEY


@dataclass(frozen=True)
class Frame:
    """One MAVLink frame as generated, with what a decoder must find in it."""

    data: bytes
    sysid: int
    compid: int
    seq: int
    msgid: int
    version: int  # 1 or 2
    signed: bool = False
    crc: str = "ok"  # "ok", "bad" or "unchecked" (message id unknown, so CRC_EXTRA unknown)


class Endpoint:
    """One MAVLink sender (a vehicle or a GCS): pymavlink does the encoding, signing and sequencing."""

    def __init__(self, dialect: ModuleType, sysid: int, compid: int, *, link_id: int | None = None) -> None:
        self.dialect = dialect
        self.v1 = dialect.WIRE_PROTOCOL_VERSION == "1.0"
        self.mav: Any = dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        if link_id is not None:
            # Set by hand rather than through mavutil.setup_signing(), which takes time.time().
            self.mav.signing.secret_key = SIGNING_KEY
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = link_id

    def pack(self, msg: Any, t_us: int) -> Frame:
        """Encode `msg` as sent at capture time `t_us` and advance the sequence number."""
        mav = self.mav
        signed = mav.signing.sign_outgoing
        if signed:  # signature timestamps follow the capture clock and never go backwards
            mav.signing.timestamp = max(mav.signing.timestamp, (t_us - SIGNING_EPOCH_US) // 10)
        seq = mav.seq
        data = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return Frame(data, mav.srcSystem, mav.srcComponent, seq, msg.get_msgId(), 1 if self.v1 else 2, signed)

    def next_seq(self) -> int:
        """Take a sequence number for a frame built by hand."""
        seq = self.mav.seq
        self.mav.seq = (seq + 1) % 256
        return seq


def v2_frame(msgid: int, payload: bytes, seq: int, sysid: int, compid: int, crc_extra: int,
             incompat: int = 0) -> bytes:
    """A MAVLink v2 frame built by hand (for message ids or flags pymavlink will not produce)."""
    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), incompat, 0, seq, sysid, compid,
                         msgid & 0xFFFF, msgid >> 16)
    crc = mav2.x25crc(header[1:] + payload)
    crc.accumulate(bytes([crc_extra]))
    return header + payload + struct.pack("<H", crc.crc)


def frame_crc_ok(data: bytes) -> bool:
    """Whether a complete v1/v2 frame of a common.xml message has a good CRC (for self-checks)."""
    if data[0] == 0xFE:
        hlen, msgid = 6, data[5]
    else:
        hlen, msgid = 10, data[7] | data[8] << 8 | data[9] << 16
    end = hlen + data[1]
    crc = mav2.x25crc(data[1:end])
    crc.accumulate(bytes([mav2.mavlink_map[msgid].crc_extra]))
    return struct.unpack_from("<H", data, end)[0] == crc.crc


def assert_no_stx(data: bytes, what: str) -> None:
    """Damaged bytes must not hide a 0xFD/0xFE that could start another candidate frame."""
    if b"\xfd" in data or b"\xfe" in data:
        raise AssertionError(f"{what} contains a MAVLink start byte: {data.hex()}")


@dataclass
class Send:
    """One write by one endpoint: the payload of one UDP datagram, or a chunk written to a stream."""

    t_us: int  # microseconds since the capture start
    side: str  # "vehicle" or "gcs"
    frames: list[Frame]
    urgent: bool = False  # a reply in a transaction: a stream writer flushes it at once
