"""MAVLink sequence numbers of one sender: loss, duplicates, reordering, and each frame's position.

SEQ is an 8-bit counter per sender. `SeqTracker.feed(seq)` classifies each frame's step from the last
one: `next` (+1), `gap` (ahead by d < 128: d - 1 frames missing), `late` (behind, filling a slot still
missing: one frame less lost), `duplicate` (behind or equal, filling nothing). Gaps of more than 127
cannot be told from late frames and count as late. Loss is what stays missing: a frame that comes late
or from a second counter of the same sender (ground stations send REQUEST_DATA_STREAM on one of
its own: the expert's `seq-own-counter`) is not lost, so the Links table and the `seq-gap` findings
tell the same story.

`position` is the frame's place in the sender's unwrapped sequence (it never wraps): a late frame is
placed behind the newest one, not after it. Replay detection compares positions, so a frame repeated
byte for byte 256 frames later (a neutral-stick MANUAL_CONTROL after the counter wrapped) is told from a
copy of a frame the counter has not yet left behind.

A frame with the sequence number of the frame before it is a duplicate only when it is a copy of it. With
other contents (`raw` given and different) the sender did not count it: those are `unchanged`, neither
duplicates nor losses. One known cause: MAVProxy writes the parameters it fetched over FTP into its tlog
as PARAM_VALUE frames that all carry one number; test vectors written with seq 0 are another.

A sender that reboots restarts its counter: its frames then step back without filling a gap. When
RESET_RUN such frames in a row each continue the previous one (+1), the counter restarted (or moved to
another channel): they were not duplicates, the counter is followed from there, and `resets` counts it.

MAVLink keeps one counter per channel (the C library's `mavlink_status_t` per `mavlink_channel_t`): a
ground station talking to two vehicles over two links numbers each link's frames on its own, so its
frames from two endpoints interleave two counters. `SeqChannels` follows a sender per channel, a channel
being the frame's source and destination endpoints (a tlog or a raw stream shows none: one channel per
sender), and sums a sender's channels for the Links table and the findings.

State is bounded: at most 127 missing slots, and the large gaps remembered for findings are capped; at most
MAX_CHANNELS channels per sender and MAX_EXTRA channels beyond each sender's first in all (more share one
counter, as before channels were told apart). A tracker is small (a capture can make some 70,000 of them,
one per sender and channel, two per sender with the expert's): its missing slots are one byte each, made at
its first gap.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import NamedTuple

from mavscope.mavlink.frame import Frame

LATE_WINDOW = 128
GAP_MIN = 10  # a gap of this many frames or more is listed in the `seq-gap` finding
GAPS_KEPT = 50  # large gaps remembered per sender (their count is kept beyond that)
RESET_RUN = 10  # backward frames in a row, each one after the other, that make a restarted counter
MAX_CHANNELS = 8  # channels followed apart per sender
MAX_EXTRA = 4096  # channels beyond each sender's first, in all
SHARED = ("*", "*")  # the channel the channels beyond those limits share


@dataclass(slots=True)
class Gap:
    """A run of missing sequence numbers, found when the frame after it arrived."""

    record: int  # the frame that revealed it
    before: int  # seq before the gap
    after: int  # seq after it
    size: int
    remaining: int  # still missing (late frames fill it)


MISSING_NOT, MISSING_SMALL = 0, 1  # a slot of `SeqTracker.missing`; 2 + i: in the large gap `gaps[i]`


@dataclass(slots=True)
class SeqTracker:
    """Sequence-number bookkeeping for one sender. `feed(seq, record)` returns what the number was."""

    last: int | None = None
    lost: int = 0
    duplicates: int = 0  # frames that repeat a sequence number already seen (`repeats` of them: the last one)
    repeats: int = 0
    unchanged: int = 0  # frames with the previous frame's number and other contents: not counted by the sender
    reordered: int = 0
    resets: int = 0  # the counter restarted (a reboot) or moved to another channel
    position: int = 0  # of the frame fed last
    newest: int = 0  # position of the newest frame (the one `last` belongs to)
    missing: bytearray | None = None  # per seq: MISSING_NOT, MISSING_SMALL or 2 + its large gap's index in `gaps`
    gaps: list[Gap] = field(default_factory=list)  # large gaps, the first GAPS_KEPT
    large_gaps: int = 0  # how many large gaps in all
    run: int = 0  # backward frames in a row, each following the previous one
    run_seq: int = 0  # the seq of the last of them
    last_raw: bytes | None = None  # the bytes of the frame fed last (when given)

    def feed(self, seq: int, record: int = 0, raw: bytes | None = None) -> tuple[str, int]:
        """("first" | "next" | "gap" | "duplicate" | "unchanged" | "late" | "reset", frames lost by this
        step). `raw`, the frame's bytes, tells a copy of the frame before from a frame the sender did not
        count."""
        previous, self.last_raw = self.last_raw, raw
        if self.last is None:
            self.last = seq
            return "first", 0
        d = (seq - self.last) % 256
        behind_run, self.run = self.run, 0
        if d == 1:
            self._advance(seq, 1)
            return "next", 0
        if d == 0:
            if raw is not None and previous is not None and raw != previous:
                self.unchanged += 1
                self.position = self.newest
                return "unchanged", 0
            self.duplicates += 1
            self.repeats += 1
            self.position = self.newest
            return "duplicate", 0
        if d < LATE_WINDOW:
            mark = MISSING_SMALL
            if d - 1 >= GAP_MIN:
                self.large_gaps += 1
                if len(self.gaps) < GAPS_KEPT:
                    mark = 2 + len(self.gaps)
                    self.gaps.append(Gap(record, self.last, seq, d - 1, d - 1))
            missing = self.missing
            if missing is None:
                missing = self.missing = bytearray(256)
            for k in range(1, d):  # ahead of `last`: no slot of an earlier gap (those are at most 127 behind)
                missing[(self.last + k) % 256] = mark
            self.lost += d - 1
            self._advance(seq, d)
            return "gap", d - 1
        self.position = self.newest - (256 - d)
        missing = self.missing
        mark = MISSING_NOT if missing is None else missing[seq]
        if mark != MISSING_NOT:
            missing[seq] = MISSING_NOT  # type: ignore[index]  # a mark is only read from an array
            if mark >= 2:
                self.gaps[mark - 2].remaining -= 1
            self.lost -= 1
            self.reordered += 1
            return "late", -1
        self.duplicates += 1
        self.run = behind_run + 1 if behind_run and seq == (self.run_seq + 1) % 256 else 1
        self.run_seq = seq
        if self.run >= RESET_RUN:  # a restarted counter, not duplicates: follow it from here
            self.duplicates -= self.run
            self.resets += 1
            self.run = 0
            self.missing = None  # the old counter's missing frames stay lost
            self._advance(seq, 256)
            return "reset", 0
        return "duplicate", 0

    def _advance(self, seq: int, d: int) -> None:
        """`seq` is the newest, `d` steps on: the slots now LATE_WINDOW or more behind it are no longer
        missing (they were at most 127 behind the last: those now 128 to 127 + d behind)."""
        self.last = seq
        self.newest += d
        self.position = self.newest
        missing = self.missing
        if missing is not None:
            for k in range(min(d, 256 - LATE_WINDOW)):
                missing[(seq - LATE_WINDOW - k) % 256] = MISSING_NOT

    @property
    def lost_in_large_gaps(self) -> int:
        return sum(g.remaining for g in self.gaps)


Sender = tuple[int, int]
Endpoints = tuple[str, str]  # (source, destination) as text; ("", "") where the capture has no addresses


class SeqTotals(NamedTuple):
    """A sender's counts summed over its channels."""

    lost: int
    duplicates: int
    repeats: int
    unchanged: int
    reordered: int


def totals(trackers: Iterable[SeqTracker]) -> SeqTotals:
    lost = duplicates = repeats = unchanged = reordered = 0
    for tr in trackers:
        lost += tr.lost
        duplicates += tr.duplicates
        repeats += tr.repeats
        unchanged += tr.unchanged
        reordered += tr.reordered
    return SeqTotals(lost, duplicates, repeats, unchanged, reordered)


def endpoints(f: Frame) -> Endpoints:
    """The channel a frame travels on: its source and destination endpoints."""
    return ("" if f.src is None else f.src.text, "" if f.dst is None else f.dst.text)


class SeqChannels:
    """One `SeqTracker` per sender and channel (`tracker(frame)`); `senders` maps each sender to its
    channels' trackers."""

    def __init__(self) -> None:
        self.senders: dict[Sender, dict[Endpoints, SeqTracker]] = {}
        self.extra = 0

    def tracker(self, f: Frame) -> SeqTracker:
        return self.tracker_for((f.sysid, f.compid), endpoints(f))

    def tracker_for(self, sender: Sender, ends: Endpoints) -> SeqTracker:
        """The tracker of `sender`'s frames on channel `ends` (made at its first frame, within the limits)."""
        chans = self.senders.get(sender)
        if chans is None:
            chans = self.senders[sender] = {}
        tr = chans.get(ends)
        if tr is None:
            if chans and (len(chans) >= MAX_CHANNELS or self.extra >= MAX_EXTRA):
                ends = SHARED
                tr = chans.get(ends)
            if tr is None:
                self.extra += 1 if chans else 0
                tr = chans[ends] = SeqTracker()
        return tr

    def feed(self, f: Frame) -> tuple[str, int]:
        """What the frame's sequence number was on its channel (`SeqTracker.feed`)."""
        return self.tracker(f).feed(f.seq, f.record, f.raw)

    def totals(self, sender: Sender) -> SeqTotals:
        return totals(self.senders.get(sender, {}).values())
