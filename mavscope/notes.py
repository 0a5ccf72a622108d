"""Annotations ("expert info") attached to frames: registered codes with a severity.

Bad input never vanishes: whatever the readers, the transport layer or the framer could not use
becomes a Note with a code from this registry, a severity and, where known, a file offset.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Severity(str, Enum):
    """Wireshark's expert-info severities, lowest first."""

    CHAT = "chat"
    NOTE = "note"
    WARN = "warn"
    ERROR = "error"


@dataclass(frozen=True, slots=True)
class NoteCode:
    code: str
    severity: Severity
    summary: str


# The registry of every note code mavscope emits. Codes are stable: they appear in JSON output and filters.
CODES: dict[str, NoteCode] = {
    c.code: c
    for c in (
        # capture readers
        NoteCode("record-truncated", Severity.WARN, "capture record shorter than its header says"),
        NoteCode("record-snapped", Severity.NOTE, "record captured with fewer bytes than were on the wire"),
        NoteCode("capture-garbage", Severity.WARN, "unparseable bytes in the capture file were skipped"),
        NoteCode("unknown-linktype", Severity.NOTE, "link type mavscope does not decode"),
        # transport
        NoteCode("malformed-packet", Severity.WARN, "link, IP, UDP or TCP header is malformed"),
        NoteCode("ip-fragment", Severity.NOTE, "IP fragment: not reassembled"),
        NoteCode("tcp-gap", Severity.WARN, "bytes missing from a TCP stream"),
        NoteCode("tcp-retransmission", Severity.CHAT, "TCP retransmission dropped"),
        NoteCode("tcp-suspicious-syn", Severity.WARN, "SYN with a new sequence number in an established TCP stream"),
        # framing
        NoteCode("skipped-bytes", Severity.WARN, "bytes that are not MAVLink were skipped"),
        NoteCode("truncated-frame", Severity.WARN, "frame cut short by the end of its packet or stream"),
        NoteCode("bad-crc", Severity.ERROR, "CRC does not match"),
        NoteCode("unknown-msgid", Severity.NOTE, "message id not in the loaded dialects: CRC unchecked"),
        NoteCode("length-mismatch", Severity.WARN, "payload length does not fit the message definition"),
        NoteCode("unknown-incompat-flags", Severity.WARN, "incompatibility flags mavscope does not know"),
        NoteCode("encrypted-payload", Severity.NOTE, "payload encrypted (incompat flag bits 5-7)"),
        NoteCode("v1-nonzero-padding", Severity.CHAT, "trailing zero bytes present in a v2 payload"),
        # security (mavscope.security)
        NoteCode("unsigned-in-signed-stream", Severity.WARN, "unsigned frame from a sender that signs its frames"),
        NoteCode("key-leak", Severity.ERROR, "SETUP_SIGNING carries a signing key in clear"),
        NoteCode("signature-skew", Severity.NOTE, "new signing stream more than a minute from capture time"),
        NoteCode("key-exchange", Severity.NOTE, "MAVSCOPE_KEY_EXCHANGE public key (ECDH epoch)"),
        NoteCode("nonce-reuse", Severity.ERROR, "aes-gcm nonce used twice under one key"),
    )
}


@dataclass(frozen=True, slots=True)
class Note:
    """One annotation: a registered code, its severity, a human message and the file offset if known."""

    code: str
    severity: Severity
    message: str
    offset: int | None = None

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {"code": self.code, "severity": self.severity.value, "message": self.message}
        if self.offset is not None:
            out["offset"] = self.offset
        return out


def note(code: str, message: str | None = None, offset: int | None = None) -> Note:
    """Build a Note for a registered code (KeyError for an unregistered one: codes are a closed set)."""
    nc = CODES[code]
    return Note(code, nc.severity, message if message is not None else nc.summary, offset)
