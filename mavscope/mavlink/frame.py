"""The MAVLink frame record, its verdict enums, and the one reading of a frame's signature state."""

from __future__ import annotations

from datetime import datetime, timezone
from enum import Enum
from functools import lru_cache
from typing import NamedTuple

from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import MessageDef
from mavscope.notes import Note
from mavscope.wire import HEADER_V1, HEADER_V2, IFLAG_SIGNED

Addr = tuple[int, int]  # a MAVLink system and component: (sysid, compid)

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


class SignatureReason(str, Enum):
    """Why a frame's signing got its verdict (the words are shown in the detail tree)."""

    MAC_OK = "mac verifies"
    NEW_STREAM = "first frame of its stream"
    NO_KEY_MATCHES = "no supplied key verifies the MAC"
    NOT_NEWER = "timestamp not newer than the last accepted one of its stream"
    NO_KEY = "no key supplied"
    TRUNCATED = "signature block truncated"
    UNSIGNED_IN_SIGNED_STREAM = "unsigned frame in a signed stream"  # an unsigned v2 frame: no status
    V1_IN_SIGNED_STREAM = "MAVLink v1 frame from a signing sender"  # v1 cannot be signed: no status


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
    """Verdicts of the security layer on one frame (None on a Frame that layer has nothing to say about)."""

    signature_status: SignatureStatus | None  # None for unsigned frames (and signed ones it did not judge)
    key: str | None  # the NAME of the key whose MAC matched (valid or replay); never the key itself
    encryption: Encryption | None  # None for plaintext frames
    reason: SignatureReason | None = None
    detail: str = ""  # numbers for the reason (timestamps, skew); never key material
    skew: float | None = None  # a new signing stream: signature time - capture time, seconds

    @property
    def reason_text(self) -> str:
        """The reason in words, with its numbers: "first frame of its stream (signature time +0.002 s ...)"."""
        if self.reason is None:
            return ""
        return self.reason.value + (f" ({self.detail})" if self.detail else "")

    @property
    def unsigned_in_signed_stream(self) -> bool:
        """An unsigned v2 frame from a sender that signs (a downgrade or an injection)."""
        return self.reason is SignatureReason.UNSIGNED_IN_SIGNED_STREAM

    @property
    def v1_in_signed_stream(self) -> bool:
        """A v1 frame (it cannot carry a signature) from a sender that signs: signing is not in force."""
        return self.reason is SignatureReason.V1_IN_SIGNED_STREAM


def signature_status(incompat_flags: int, security: Security | None) -> SignatureStatus | None:
    """A frame's signature state, the one rule everything uses: the security stage's verdict; `no-key`
    for a frame flagged signed that it did not judge (no key material); None for an unsigned frame."""
    if security is not None and security.signature_status is not None:
        return security.signature_status
    return SignatureStatus.NO_KEY if incompat_flags & IFLAG_SIGNED else None


def frame_number(record: int, index: int) -> str:
    """Wireshark's frame number: the record, with the frame's index within it after a dot ("12", "12.2")."""
    return str(record) if index == 1 else f"{record}.{index}"


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
    rows it shows). A NamedTuple rather than a frozen dataclass: a million are built per capture and a
    tuple is built several times faster (docs/performance.md). Build one with `new_frame`, the one
    place that lays out its fields, and read it by attribute name.
    """

    record: int  # capture record number where the frame completed (1-based)
    # index: 1-based position of the frame among the frames completed in that record (shadows tuple.index)
    index: int  # type: ignore[assignment]
    time: float | None  # capture time of that record
    transport: str  # "udp" | "tcp" | "tlog" | "raw"
    src: Endpoint | None
    dst: Endpoint | None
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
    def number(self) -> str:
        return frame_number(self.record, self.index)

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

    @property
    def signature_status(self) -> SignatureStatus | None:
        return signature_status(self.incompat_flags, self.security)


_new = tuple.__new__


def new_frame(
    record: int, index: int, time: float | None, transport: str, src: Endpoint | None, dst: Endpoint | None,
    offset: int | None, raw: bytes, version: int, length: int, incompat_flags: int, compat_flags: int, seq: int,
    sysid: int, compid: int, msgid: int, crc: int | None, crc_status: CrcStatus, msgdef: MessageDef | None,
    signature: Signature | None, notes: tuple[Note, ...], span: tuple[int, ...] | None,
) -> Frame:
    """A Frame without the NamedTuple constructor's Python-level overhead (the security slot empty)."""
    return _new(Frame, (record, index, time, transport, src, dst, offset, raw, version, length, incompat_flags,
                        compat_flags, seq, sysid, compid, msgid, crc, crc_status, msgdef, signature, notes, span,
                        None))


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
