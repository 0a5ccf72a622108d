"""`mavscope verify`: signature verdicts counted per sender, and the frames that fail the check.

The computation behind the command (`commands/verify.py` renders it): every frame goes through
`VerifyReport.add`, which counts it in its sender's row and lists what is wrong with it; `finish()` at the
end adds the unsigned frames of signing senders that came before their first signed frame (Downgrades:
the verdict does not depend on the order of frames).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

from mavscope.mavlink.frame import Frame, SignatureReason, SignatureStatus
from mavscope.security.downgrade import Downgrades

PROBLEMS_KEPT = 10_000  # problems listed (all are counted)


@dataclass
class StreamRow:
    """What one sender (sysid, compid) sent, by signature verdict."""

    links: set[int] = field(default_factory=set)
    frames: int = 0
    signed: int = 0
    valid: int = 0
    invalid: int = 0
    replay: int = 0
    no_key: int = 0
    unsigned: int = 0
    injected: int = 0  # unsigned v2 frames from a sender that signs (unsigned-in-signed-stream)
    v1: int = 0  # MAVLink v1 frames from a sender that signs (v1-in-signed-stream): signing not in force
    keys: set[str] = field(default_factory=set)
    skew: list[float] = field(default_factory=list)  # signature - capture time of each new stream

    @property
    def failed(self) -> bool:
        return bool(self.invalid or self.replay or self.injected)

    def to_json(self, sysid: int, compid: int) -> dict[str, object]:
        return {"sysid": sysid, "compid": compid, "links": sorted(self.links), "frames": self.frames,
                "signed": self.signed, "valid": self.valid, "invalid": self.invalid, "replay": self.replay,
                "no_key": self.no_key, "unsigned": self.unsigned, "unsigned_in_signed_stream": self.injected,
                "v1_in_signed_stream": self.v1,
                "keys": sorted(self.keys)}


@dataclass
class VerifyReport:
    """Rows per sender and the problems found, in capture order."""

    rows: dict[tuple[int, int], StreamRow] = field(default_factory=lambda: defaultdict(StreamRow))
    problems: list[tuple[int, int, str]] = field(default_factory=list)  # (record, index, what is wrong)
    problem_count: int = 0  # all of them (PROBLEMS_KEPT are listed)
    downgrades: Downgrades = field(default_factory=Downgrades)

    @property
    def failed(self) -> bool:
        return any(r.failed for r in self.rows.values())

    @property
    def v1_frames(self) -> int:
        """MAVLink v1 frames from senders that sign: they cannot be signed, so signing is not in force."""
        return sum(r.v1 for r in self.rows.values())

    @property
    def all_checked(self) -> bool:
        """Every signed frame had a key to check it with."""
        return all(r.no_key == 0 for r in self.rows.values())

    def _problem(self, f: Frame, message: str) -> None:
        self.problem_count += 1
        if len(self.problems) < PROBLEMS_KEPT:
            self.problems.append((f.record, f.index, message))

    def finish(self) -> None:
        """The end of the capture: the unsigned frames of signing senders from before their first signed
        frame counted as those after it are, and the problems put in frame order."""
        for j in self.downgrades.judged():
            row = self.rows[j.sender]
            row.injected += j.v2
            row.v1 += j.v1
            sender = f"{j.sender[0]}/{j.sender[1]}"
            self.problem_count += j.v2
            self.problems += [(r, i, f"unsigned {what} from {sender}, which signs its frames (before its first "
                                     "signed frame)") for r, i, what in j.listed_v2]
        self.problems.sort(key=lambda p: (p[0], p[1]))
        del self.problems[PROBLEMS_KEPT:]
        self.downgrades = Downgrades()

    def add(self, f: Frame) -> None:
        self.downgrades.add(f)
        row = self.rows[(f.sysid, f.compid)]
        row.frames += 1
        sender = f"{f.sysid}/{f.compid}"
        what = f.msgname or f.msgid
        sec = f.security
        if f.signature is not None:
            row.signed += 1
            row.links.add(f.signature.link_id)
            status = f.signature_status
            if status is SignatureStatus.VALID:
                row.valid += 1
            elif status is SignatureStatus.INVALID:
                row.invalid += 1
                self._problem(f, f"invalid signature ({what} from {sender})")
            elif status is SignatureStatus.REPLAY:
                row.replay += 1
                self._problem(f, f"replay ({what} from {sender}, link {f.signature.link_id})")
            else:
                row.no_key += 1
            if sec is not None and sec.key:
                row.keys.add(sec.key)
            if sec is not None and sec.reason is SignatureReason.NEW_STREAM and f.time is not None:
                row.skew.append(f.signature.unix_time - f.time)
        else:
            row.unsigned += 1
            if sec is not None and sec.unsigned_in_signed_stream:
                row.injected += 1
                self._problem(f, f"unsigned {what} from {sender}, which signs its frames")
            elif sec is not None and sec.v1_in_signed_stream:
                row.v1 += 1
        for n in f.notes:
            if n.code == "key-leak":
                self._problem(f, "SETUP_SIGNING: signing key sent in clear")
