"""Expert findings: what an analysis concluded about a capture, with severity and the frames involved.

Shared by `audit`, `stats`, the forensic commands and the TUI's expert screen. Codes are stable: they
appear in JSON output.
"""

from __future__ import annotations

from dataclasses import dataclass

from mavscope.notes import Severity


@dataclass(frozen=True, slots=True)
class Finding:
    code: str  # e.g. "key-leak", "replay", "bad-crc-burst"
    severity: Severity
    message: str
    frames: tuple[int, ...] = ()  # capture record numbers of the frames involved (Wireshark's frame numbers)

    def to_json(self) -> dict[str, object]:
        return {"code": self.code, "severity": self.severity.value, "frames": list(self.frames),
                "message": self.message}


SEVERITY_ORDER = {Severity.ERROR: 0, Severity.WARN: 1, Severity.NOTE: 2, Severity.CHAT: 3}


def sort_findings(findings: list[Finding]) -> list[Finding]:
    """Most severe first, then by first frame."""
    return sorted(findings, key=lambda f: (SEVERITY_ORDER[f.severity], f.frames[:1], f.code))
