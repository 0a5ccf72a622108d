"""The MAVLink frame record and its verdict enums."""

from __future__ import annotations

from datetime import datetime, timezone
from enum import Enum
from functools import lru_cache
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


class EncryptionStatus(str, Enum):
    DECRYPTED = "decrypted"
    NO_KEY = "no-key"
    FAILED = "failed"


class Encryption(NamedTuple):
    """What the security layer did with an encrypted payload (incompat flag bits 5-7)."""

    method: int  # 1..7: incompat_flags >> 5
    scheme: str | None  # "xor", "aes-128-ctr", "aes-gcm"; None when no cipher is configured for the method
    status: EncryptionStatus
    plaintext: bytes | None  # the decrypted payload (status DECRYPTED)
    reason: str = ""  # why it failed, for the notes and the tree


class Security(NamedTuple):
    """Verdicts of the security layer on one frame (None on a Frame that layer has not seen)."""

    signature_status: SignatureStatus | None  # None for unsigned frames
    key: str | None  # the NAME of the key whose MAC matched (valid or replay); never the key itself
    encryption: Encryption | None  # None for plaintext frames
    reason: str = ""  # why the signature verdict is what it is (replay: last accepted timestamp...)


class Signature(NamedTuple):
    link_id: int
    timestamp: int  # units of 10 microseconds since 2015-01-01T00:00:00Z
    value: bytes  # 6 bytes

    @property
    def unix_time(self) -> float:
        return SIGNING_EPOCH + self.timestamp / 100_000

    def iso_time(self) -> str:
        """The timestamp as ISO-8601 UTC to its 10 µs resolution, e.g. 2026-03-14T10:00:00.00075Z."""
        seconds, frac = divmod(self.timestamp, 100_000)
        return f"{_iso_second(seconds)}.{frac:05d}Z"


@lru_cache(maxsize=4096)
def _iso_second(seconds: int) -> str:
    """ISO-8601 text of a whole second of the signing epoch (cached: signed frames share their seconds)."""
    try:
        dt = datetime.fromtimestamp(SIGNING_EPOCH + seconds, tz=timezone.utc)
    except (OverflowError, OSError, ValueError):  # 48-bit timestamps reach far past datetime's range
        return f"+{seconds}s-since-2015-01-01T00:00:00"
    return dt.strftime("%Y-%m-%dT%H:%M:%S")


class Frame(NamedTuple):
    """One MAVLink frame as found in a capture, with its header, CRC verdict and context.

    The payload is not decoded here: `decode_payload` does that on demand (the TUI decodes only the
    rows it shows). Built with `tuple.__new__` on the hot path (see docs/performance.md).
    """

    record: int  # capture record number where the frame completed (1-based)
    # index: 1-based position of the frame among the frames completed in that record (shadows tuple.index)
    index: int  # type: ignore[assignment]
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
    security: Security | None = None  # set by the security layer (mavscope.security) when it runs

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



def plaintext_payload(frame: Frame) -> bytes | None:
    """The payload to decode: the wire payload of a plaintext frame, the decrypted one of an encrypted
    frame the security layer could decrypt, else None."""
    if frame.msgdef is None or frame.crc_status is CrcStatus.TRUNCATED:
        return None
    iflags = frame.incompat_flags
    if not iflags & ~KNOWN_IFLAGS:
        return frame.payload
    sec = frame.security
    if (iflags & ~(KNOWN_IFLAGS | IFLAG_ENCRYPTION_MASK)) == 0 and sec is not None and sec.encryption is not None:
        return sec.encryption.plaintext
    return None


def decode_payload(frame: Frame) -> dict[str, object] | None:
    """Raw field values of the frame's payload (decrypted where it was encrypted and could be
    decrypted), or None where it cannot be decoded."""
    payload = plaintext_payload(frame)
    if payload is None:
        return None
    return frame.msgdef.decode(payload)  # type: ignore[union-attr]
