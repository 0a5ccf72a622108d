"""Verdict glyphs and colours, shared by the packet list, the detail tree and the help screen.

Bad CRC and invalid signatures red, replays and unsigned frames in a signed stream orange, valid
green; encrypted and decrypted payloads marked. Each glyph is one cell wide, and the glyphs of a column
differ from each other, so that the verdicts read without colour (a monochrome terminal, NO_COLOR, a
colour-blind analyst): ✗ and X a check that failed, … a frame cut short.
"""

from __future__ import annotations

from mavscope.mavlink.frame import (
    IFLAG_ENCRYPTION_MASK,
    CrcStatus,
    EncryptionStatus,
    Security,
    SignatureStatus,
    signature_status,
)

RED = "bold #ff5f5f"
ORANGE = "bold #ffaf00"
GREEN = "#5fd75f"
BLUE = "#5fafff"
DIM = "#808080"

CRC_GLYPHS: dict[CrcStatus, tuple[str, str, str]] = {
    # status: (glyph, style, meaning)
    CrcStatus.OK: ("✓", GREEN, "CRC ok"),
    CrcStatus.BAD: ("✗", RED, "CRC bad"),
    CrcStatus.UNCHECKED: ("?", DIM, "CRC unchecked (unknown message id)"),
    CrcStatus.TRUNCATED: ("…", RED, "frame truncated before its CRC"),
}

SIGNATURE_GLYPHS: dict[str, tuple[str, str, str]] = {
    SignatureStatus.VALID.value: ("S", GREEN, "signature valid"),
    SignatureStatus.INVALID.value: ("X", RED, "signature invalid"),
    SignatureStatus.REPLAY.value: ("R", ORANGE, "replayed signature (timestamp not increasing)"),
    SignatureStatus.NO_KEY.value: ("s", DIM, "signed, no key to check it (k adds one)"),
    SignatureStatus.TRUNCATED.value: ("…", RED, "signature truncated"),
    "unsigned": ("U", ORANGE, "unsigned frame in a signed stream"),
    "v1": ("1", ORANGE, "MAVLink v1 frame from a signing sender (cannot be signed)"),
}

ENCRYPTION_GLYPHS: dict[str, tuple[str, str, str]] = {
    EncryptionStatus.DECRYPTED.value: ("D", BLUE, "payload decrypted"),
    EncryptionStatus.NO_KEY.value: ("E", ORANGE, "payload encrypted, no cipher key (k adds one)"),
    EncryptionStatus.FAILED.value: ("X", RED, "payload encrypted, decryption failed"),
}


def signature_key(iflags: int, security: Security | None) -> str | None:
    """The SIGNATURE_GLYPHS key for a frame, or None (unsigned, nothing to say)."""
    status = signature_status(iflags, security)
    if status is not None:
        return status.value
    if security is not None and security.unsigned_in_signed_stream:
        return "unsigned"
    if security is not None and security.v1_in_signed_stream:
        return "v1"
    return None


def encryption_key(iflags: int, status: object) -> str | None:
    """The ENCRYPTION_GLYPHS key for a frame, or None (plaintext)."""
    if status is not None:
        return getattr(status, "value", str(status))
    if iflags & IFLAG_ENCRYPTION_MASK:
        return EncryptionStatus.NO_KEY.value
    return None


def legend() -> list[tuple[str, str, str]]:
    """Every glyph with its style and meaning (for the help screen)."""
    return list(CRC_GLYPHS.values()) + list(SIGNATURE_GLYPHS.values()) + list(ENCRYPTION_GLYPHS.values())
