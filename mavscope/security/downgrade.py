"""Unsigned and MAVLink v1 frames from senders that sign, judged with the whole capture.

The security stage notes `unsigned-in-signed-stream` and `v1-in-signed-stream` on a frame as it comes: it
knows a sender signs once it has seen one of its signed frames, so an unsigned command claiming that
sender placed before its first signed frame passed unnoted. A receiver with signing configured refuses
it wherever it comes (its key, not the order of frames, makes it enforce signing), and offline the
whole capture is known: `Downgrades` keeps, per sender not yet known to sign, its unsigned frames
(counted, the first EARLY_LISTED listed, EARLY_TOTAL listed over all senders) and, at the end, gives
those of the senders that turned out to sign, as the stage would have noted them had it known. `verify`
and `audit` count them with the stage's notes, so their verdicts do not depend on the order of frames.

A sender signs by the stage's rule, read back from its verdicts (`signs`): a signed frame whose MAC a key
verified, or, where no signing key material was given, a signed frame with a good CRC.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from itertools import islice

from mavscope.mavlink.frame import CrcStatus, Frame, SignatureStatus
from mavscope.security.stage import RADIO_STATUS
from mavscope.wire import IFLAG_SIGNED

EARLY_LISTED = 1_000  # unsigned frames listed per sender before it is known to sign (all are counted)
EARLY_TOTAL = 100_000  # and over all senders

Sender = tuple[int, int]
Listed = tuple[int, int, str]  # (record, index in the record, message name)


def signs(f: Frame) -> bool:
    """Whether `f` shows its sender signing, by the security stage's rule (stage.SecurityStage.process): a
    signed frame the stage found valid, or, where it checked no signature (no key material), a signed
    frame with a good CRC."""
    if f.version != 2 or not f.incompat_flags & IFLAG_SIGNED:
        return False
    sec = f.security
    status = None if sec is None else sec.signature_status
    return status is SignatureStatus.VALID or (status is None and f.crc_status is CrcStatus.OK)


def unsigned(f: Frame) -> bool:
    """Whether `f` carries no signature (a v1 frame, or a v2 frame without the signed flag)."""
    return f.version != 2 or not f.incompat_flags & IFLAG_SIGNED


@dataclass(slots=True)
class Early:
    """One sender's unsigned frames before it was known to sign: v2 and v1 counted, the first listed."""

    v2: int = 0
    v1: int = 0
    listed: list[tuple[int, int, int, str]] = field(default_factory=list)  # (version, record, index, name)


@dataclass(frozen=True, slots=True)
class Judged:
    """A signing sender's unsigned frames that came before its first signed frame."""

    sender: Sender
    v2: int  # unsigned v2 frames: unsigned-in-signed-stream
    v1: int  # MAVLink v1 frames: v1-in-signed-stream
    listed_v2: tuple[Listed, ...]
    listed_v1: tuple[Listed, ...]


class Downgrades:
    """`add(frame)` per frame after the security stage, in capture order; `judged()` at the end."""

    def __init__(self) -> None:
        self.signers: set[Sender] = set()
        self.early: dict[Sender, Early] = {}
        self.listed = 0

    def add(self, f: Frame) -> None:
        sender = (f.sysid, f.compid)
        if sender in self.signers:
            return  # the stage judges its unsigned frames from here on
        if signs(f):
            self.signers.add(sender)
            return
        if not unsigned(f) or f.msgid == RADIO_STATUS:
            return
        e = self.early.get(sender)
        if e is None:
            e = self.early[sender] = Early()
        if f.version == 1:
            e.v1 += 1
        else:
            e.v2 += 1
        if len(e.listed) < EARLY_LISTED and self.listed < EARLY_TOTAL:
            self.listed += 1
            e.listed.append((f.version, f.record, f.index, f.msgname or str(f.msgid)))

    def room(self, sender: Sender | None = None) -> int:
        """How many more of `sender`'s unsigned frames are listed (the rest are counted): EARLY_LISTED a sender,
        EARLY_TOTAL over all of them (`sender` None: how many more over all senders)."""
        total = EARLY_TOTAL - self.listed
        if sender is None:
            return max(0, total)
        e = self.early.get(sender)
        return max(0, min(EARLY_LISTED - (0 if e is None else len(e.listed)), total))

    def unsigned_run(self, sender: Sender, v1: int, v2: int, listed: Iterable[tuple[int, int, int, str]]) -> None:
        """`v1` MAVLink v1 and `v2` unsigned v2 frames of `sender`, not RADIO_STATUS, `sender` not yet seen
        signing: what `add` does with each of them (a caller that counts frames in bulk: the export's native
        source); `listed`: (version, record, index, name) of the first of them, in capture order, of which
        `room(sender)` are kept (a caller listing across senders takes EARLY_TOTAL's share in capture order)."""
        e = self.early.get(sender)
        if e is None:
            e = self.early[sender] = Early()
        e.v1 += v1
        e.v2 += v2
        room = self.room(sender)
        if room:
            kept = list(islice(listed, room))
            e.listed += kept
            self.listed += len(kept)

    def judged(self) -> list[Judged]:
        """Per sender that signs, in the order of senders first heard, its unsigned frames before its first
        signed frame."""
        out = []
        for sender, e in self.early.items():
            if sender in self.signers:
                out.append(Judged(sender, e.v2, e.v1, tuple((r, i, n) for v, r, i, n in e.listed if v == 2),
                                  tuple((r, i, n) for v, r, i, n in e.listed if v == 1)))
        return out
