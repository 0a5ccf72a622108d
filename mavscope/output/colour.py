"""Colour for summary lines on a terminal (`read --color=auto|always|never`), in the spirit of Wireshark's
colouring rules, from the same verdict colours as the TUI (mavscope.tui.verdicts).

The first rule a frame matches colours its whole summary line: a bad or truncated CRC, an invalid or
truncated signature, a payload that failed to decrypt, or a note of severity `error`: red; a replayed
signature, an unsigned or MAVLink 1 frame of a sender that signs, or a note of severity `warn`: orange; a
valid signature: green; anything else is not coloured. `auto` (the default) colours only when standard
output is a terminal, `NO_COLOR` is not set (https://no-color.org) and TERM is not `dumb`; `always` and
`never` decide alone. The colour codes are mavscope's own SGR sequences around a line whose text from the
capture was already escaped (mavscope.visible): a capture cannot add or end a colour.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import IO

from mavscope.errors import UsageError
from mavscope.mavlink.frame import CrcStatus, EncryptionStatus, Frame, SignatureStatus
from mavscope.notes import Severity
from mavscope.tui.verdicts import GREEN, ORANGE, RED

CHOICES = ("auto", "always", "never")
RESET = "\x1b[0m"
_BAD_CRC = (CrcStatus.BAD, CrcStatus.TRUNCATED)
_BAD_SIGNATURE = (SignatureStatus.INVALID, SignatureStatus.TRUNCATED)


def sgr(style: str) -> str:
    """The SGR sequence of a TUI style (`bold #rrggbb`, `#rrggbb`): bold, and the 24-bit foreground colour."""
    codes = []
    for word in style.split():
        if word == "bold":
            codes.append("1")
        elif word.startswith("#") and len(word) == 7:
            r, g, b = (int(word[k:k + 2], 16) for k in (1, 3, 5))
            codes.append(f"38;2;{r};{g};{b}")
    return f"\x1b[{';'.join(codes)}m"


_RED, _ORANGE, _GREEN = sgr(RED), sgr(ORANGE), sgr(GREEN)


def line_colour(frame: Frame) -> str | None:
    """The SGR sequence the frame's summary line is shown in (the first rule it matches), None for none."""
    if frame.crc_status in _BAD_CRC:
        return _RED
    sec = frame.security
    status = frame.signature_status
    if status in _BAD_SIGNATURE or (sec is not None and sec.encryption is not None
                                    and sec.encryption.status is EncryptionStatus.FAILED):
        return _RED
    worst = max((n.severity.rank for n in frame.notes), default=-1)
    if worst >= Severity.ERROR.rank:
        return _RED
    if status is SignatureStatus.REPLAY or worst >= Severity.WARN.rank or (
            sec is not None and (sec.unsigned_in_signed_stream or sec.v1_in_signed_stream)):
        return _ORANGE
    if status is SignatureStatus.VALID:
        return _GREEN
    return None


def wants_colour(choice: str, out: IO[str], environ: Mapping[str, str]) -> bool:
    """Whether summary lines are coloured: `choice` (--color), standard output, NO_COLOR and TERM."""
    if choice not in CHOICES:
        raise UsageError(f"--color={choice}: one of {', '.join(CHOICES)}")
    if choice != "auto":
        return choice == "always"
    if environ.get("NO_COLOR") or environ.get("TERM") == "dumb":
        return False
    try:
        return bool(out.isatty())
    except (AttributeError, ValueError):
        return False
