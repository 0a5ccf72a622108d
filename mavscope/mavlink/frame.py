"""The MAVLink frame record and its verdict enums."""

from __future__ import annotations

from datetime import datetime, timezone
from enum import Enum
from typing import NamedTuple

from mavscope.mavlink.dialect import MessageDef
from mavscope.notes import Note

STX_V1 = 0xFE
STX_V2 = 0xFD
HEADER_V1 = 6  # STX LEN SEQ SYS COMP MSGID
HEADER_V2 = 10  # STX LEN INCOMPAT COMPAT SEQ SYS COMP MSGID(3)
SIGNATURE_LEN = 13  # link id (1), timestamp (6), signature (6)
IFLAG_SIGNED = 0x01
IFLAG_ENCRYPTION_MASK = 0xE0  # SecureMAV: method = flags >> 5
KNOWN_IFLAGS = IFLAG_SIGNED
SIGNING_EPOCH = 1420070400  # 2015-01-01T00:00:00Z; signature timestamps count 10 us from here


class CrcStatus(str, Enum):
    """CRC verdict, as Wireshark's four checksum outcomes."""

    OK = "ok"
    BAD = "bad"
    UNCHECKED = "unchecked"  # message id unknown: CRC_EXTRA unknown, so the CRC cannot be checked
    TRUNCATED = "truncated"  # the frame ends before its CRC: not enough data


class SignatureStatus(str, Enum):
    """Signature verdict. Without key material every signature is `no-key`."""

    VALID = "valid"
    INVALID = "invalid"
    NO_KEY = "no-key"
    REPLAY = "replay"
    TRUNCATED = "truncated"


class Signature(NamedTuple):
    link_id: int
    timestamp: int  # units of 10 microseconds since 2015-01-01T00:00:00Z
    value: bytes  # 6 bytes

    @property
    def unix_time(self) -> float:
        return SIGNING_EPOCH + self.timestamp / 100_000

    def iso_time(self) -> str:
        """The timestamp as ISO-8601 UTC with microseconds; out-of-range values as seconds."""
        try:
            dt = datetime.fromtimestamp(self.unix_time, tz=timezone.utc)
        except (OverflowError, OSError, ValueError):
            return f"+{self.timestamp / 100_000:.5f}s since 2015-01-01T00:00:00Z"
        return dt.isoformat(timespec="microseconds").replace("+00:00", "Z")


class Frame(NamedTuple):
    """One MAVLink frame as found in a capture, with its header, CRC verdict and context.

    The payload is not decoded here: `decode_payload` does that on demand (the TUI decodes only the
    rows it shows). Built with `tuple.__new__` on the hot path (see docs/performance.md).
    """

    record: int  # capture record number where the frame completed (1-based)
    index: int  # 1-based position of the frame among the frames completed in that record
    time: float | None  # capture time of that record
    transport: str  # "udp" | "tcp" | "tlog" | "raw"
    src: str | None
    dst: str | None
    offset: int | None  # file offset of the STX byte, where the frame lies contiguous in the file
    raw: bytes  # the frame as on the wire: header, payload, CRC, signature (truncated: what is there)
    version: int  # 1 or 2
    length: int  # LEN: payload bytes on the wire
    incompat_flags: int
    compat_flags: int
    seq: int
    sysid: int
    compid: int
    msgid: int
    crc: int | None  # None when truncated before the CRC
    crc_status: CrcStatus
    msgdef: MessageDef | None
    signature: Signature | None
    notes: tuple[Note, ...]
    span: tuple[int, ...] | None  # records holding the frame's bytes when more than `record` alone

    @property
    def header_len(self) -> int:
        return HEADER_V2 if self.version == 2 else HEADER_V1

    @property
    def payload(self) -> bytes:
        h = self.header_len
        return self.raw[h : h + self.length]

    @property
    def msgname(self) -> str | None:
        return self.msgdef.name if self.msgdef is not None else None

    @property
    def encryption_method(self) -> int:
        """SecureMAV method number from incompat flag bits 5-7 (0: plaintext)."""
        return (self.incompat_flags & IFLAG_ENCRYPTION_MASK) >> 5

    @property
    def records(self) -> tuple[int, ...]:
        return self.span if self.span is not None else (self.record,)

    def decodable(self) -> bool:
        """True when the payload can be decoded as plaintext with the message definition."""
        return (
            self.msgdef is not None
            and self.crc_status is not CrcStatus.TRUNCATED
            and not self.incompat_flags & ~KNOWN_IFLAGS
        )


def decode_payload(frame: Frame) -> dict[str, object] | None:
    """Raw field values of the frame's payload, or None where it cannot be decoded as plaintext."""
    if not frame.decodable():
        return None
    return frame.msgdef.decode(frame.payload)  # type: ignore[union-attr]
