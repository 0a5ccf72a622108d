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

One program may send as several system/component ids over one MAVLink channel, numbering all their frames
on that channel's one counter (BlueOS's mavlink-server with its own component 194 and the ground station
255/240 it speaks for; ArduSub's companion with 1/194 and GPS_INPUT from 1/220): each id alone then skips
the numbers the others used. `ChannelCounter` remembers, per channel, RING ids heard on it (an id not there
takes the place of the one there longest). When a sender's number jumps ahead and another id, heard since
the sender's last frame, last used a number inside the jump, the numbers up to that one are `taken` by
that id (`shared` while missing). A jump whose numbers are all taken, up to the one just before, is a
`full` step. Chance makes few of those: an unrelated busy sender's number lands just before in one jump of
256. A sender with SHARED_MIN full steps or more, making up half of its jumps or more, and whose `partner`
(the id of its first full step, `mate` its tracker) has as many, shares its channel's counter
(`counter_shared`): each id of one counter skips the others' numbers, while an unrelated sender's own
counter runs on without jumps. Its `missed` frames leave the taken numbers out. A frame lost from the
shared counter is missed once, by the id whose frame came next (the others' jumps end below it).

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
RING = 8  # ids remembered per channel (ChannelCounter)
SHARED_MIN = 3  # full steps at least before a sender counts as sharing its channel's counter


@dataclass(slots=True)
class Gap:
    """A run of missing sequence numbers, found when the frame after it arrived."""

    record: int  # the frame that revealed it
    before: int  # seq before the gap
    after: int  # seq after it
    size: int
    remaining: int  # still missing (late frames fill it)
    shared: int = 0  # of those, numbers another id on the channel used (SeqTracker.shared)


MISSING_NOT, MISSING_SMALL = 0, 1  # a slot of `SeqTracker.missing`; 2 + i: in the large gap `gaps[i]`
TAKEN = 0x80  # added to a slot's mark: another id on the channel used that number


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
    shared: int = 0  # missing numbers another id on the channel used (`taken`)
    full_steps: int = 0  # jumps ahead whose every skipped number another id used
    gap_steps: int = 0  # jumps ahead in all
    partner: int = -1  # sysid << 8 | compid of the id that used the numbers of the first full step
    first_full: int = -1  # the record of the frame that made the first full step
    mate: SeqTracker | None = field(default=None, repr=False, compare=False)  # the partner's tracker
    at: int = 0  # the channel's frame count at this sender's last frame (ChannelCounter)
    slot: int = -1  # its place in its ChannelCounter's ring
    channel: ChannelCounter | None = field(default=None, repr=False, compare=False)

    def feed(self, seq: int, record: int = 0, raw: bytes | None = None, taken: int = 0,
             partner: int = -1, mate: SeqTracker | None = None) -> tuple[str, int]:
        """("first" | "next" | "gap" | "duplicate" | "unchanged" | "late" | "reset", frames lost by this
        step). `raw`, the frame's bytes, tells a copy of the frame before from a frame the sender did not
        count. `taken`: of a jump ahead, the first numbers skipped that `partner` (`mate` its tracker),
        another id on the channel, used (ChannelCounter.taken)."""
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
                    self.gaps.append(Gap(record, self.last, seq, d - 1, d - 1, taken))
            missing = self.missing
            if missing is None:
                missing = self.missing = bytearray(256)
            for k in range(1, d):  # ahead of `last`: no slot of an earlier gap (those are at most 127 behind)
                missing[(self.last + k) % 256] = mark | TAKEN if k <= taken else mark
            self.gap_steps += 1
            if taken:
                self.shared += taken
                if taken == d - 1:
                    self.full_steps += 1
                    if self.first_full < 0:
                        self.partner, self.mate, self.first_full = partner, mate, record
            self.lost += d - 1
            self._advance(seq, d)
            return "gap", d - 1
        self.position = self.newest - (256 - d)
        missing = self.missing
        mark = MISSING_NOT if missing is None else missing[seq]
        if mark != MISSING_NOT:
            missing[seq] = MISSING_NOT  # type: ignore[index]  # a mark is only read from an array
            taken = mark & TAKEN
            mark &= ~TAKEN
            if taken:
                self.shared -= 1
            if mark >= 2:
                self.gaps[mark - 2].remaining -= 1
                if taken:
                    self.gaps[mark - 2].shared -= 1
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
    def counter_shared(self) -> bool:
        """The sender numbers its frames on a counter other ids on its channel share: it and its partner
        each have SHARED_MIN full steps or more, half of their jumps or more."""
        return self._skips_others() and self.mate is not None and self.mate._skips_others()

    def _skips_others(self) -> bool:
        return self.full_steps >= SHARED_MIN and 2 * self.full_steps >= self.gap_steps

    @property
    def missed(self) -> int:
        """Frames lost: the numbers still missing, less those other ids used where the counter is shared."""
        return self.lost - self.shared if self.counter_shared else self.lost

    def missed_in(self, gap: Gap) -> int:
        """The frames of `gap` lost (as `missed`)."""
        return gap.remaining - gap.shared if self.counter_shared else gap.remaining


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
        lost += tr.missed
        duplicates += tr.duplicates
        repeats += tr.repeats
        unchanged += tr.unchanged
        reordered += tr.reordered
    return SeqTotals(lost, duplicates, repeats, unchanged, reordered)


def endpoints(f: Frame) -> Endpoints:
    """The channel a frame travels on: its source and destination endpoints."""
    return ("" if f.src is None else f.src.text, "" if f.dst is None else f.dst.text)


class ChannelCounter:
    """One channel's frames, whoever sent them: how many, and RING senders heard on it (their trackers,
    the one there longest replaced first), to tell the numbers a sender skipped that another id used."""

    __slots__ = ("frames", "next", "ring", "senders")

    def __init__(self) -> None:
        self.frames = 0
        self.next = 0
        self.ring: list[SeqTracker | None] = [None] * RING
        self.senders = [-1] * RING

    def taken(self, tr: SeqTracker, last: int, d: int) -> tuple[int, int, SeqTracker | None]:
        """Of `tr`'s jump ahead by `d` (1 < d < LATE_WINDOW) from its last number `last`, the first numbers
        skipped another id used: k where another id heard since `tr`'s last frame last used `last` plus k
        (the highest such k below d), that id's sender (-1: none) and tracker."""
        best, partner, mate = 0, -1, None
        for i, other in enumerate(self.ring):
            if other is None or other is tr or other.at <= tr.at or other.last is None:
                continue
            k = (other.last - last) % 256
            if best < k < d:
                best, partner, mate = k, self.senders[i], other
        return best, partner, mate

    def admit(self, tr: SeqTracker, sender: int) -> None:
        """`tr` into the ring, in place of the one there longest."""
        tr.slot = self.next
        self.ring[self.next] = tr
        self.senders[self.next] = sender
        self.next = (self.next + 1) % RING


class SeqChannels:
    """One `SeqTracker` per sender and channel (`tracker(frame)`); `senders` maps each sender to its
    channels' trackers. A channel (but the shared one) heard from one sender only is in `alone`; heard from
    a second, its ChannelCounter is made (`counters`), the first sender's tracker in its ring before the
    second's: a channel per sender, as in a capture spraying senders, costs no counter."""

    def __init__(self) -> None:
        self.senders: dict[Sender, dict[Endpoints, SeqTracker]] = {}
        self.alone: dict[Endpoints, tuple[SeqTracker, int]] = {}  # a channel's one tracker, and its sender
        self.counters: dict[Endpoints, ChannelCounter] = {}
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
                if ends != SHARED:
                    self._join(tr, sender, ends)
        return tr

    def _join(self, tr: SeqTracker, sender: Sender, ends: Endpoints) -> None:
        """`tr`, `sender`'s new tracker, is heard on channel `ends`."""
        ch = self.counters.get(ends)
        if ch is None:
            first = self.alone.pop(ends, None)
            if first is None:
                self.alone[ends] = (tr, sender[0] << 8 | sender[1])
                return
            ch = self.counters[ends] = ChannelCounter()  # the channel's second sender
            ch.frames = first[0].at = 1
            ch.admit(*first)
            first[0].channel = ch
        tr.channel = ch

    def feed(self, f: Frame) -> tuple[str, int]:
        """What the frame's sequence number was on its channel (`SeqTracker.feed`)."""
        return self.feed_one(self.tracker(f), f.sysid << 8 | f.compid, f.seq, f.record, f.raw)

    def peek(self, sender: Sender, ends: Endpoints) -> SeqTracker | None:
        """The tracker `tracker_for` gives, None where it would make one."""
        chans = self.senders.get(sender)
        if not chans:
            return None
        tr = chans.get(ends)
        if tr is None and (len(chans) >= MAX_CHANNELS or self.extra >= MAX_EXTRA):
            tr = chans.get(SHARED)
        return tr

    @staticmethod
    def feed_one(tr: SeqTracker, sender: int, seq: int, record: int, raw: bytes) -> tuple[str, int]:
        """A frame of `sender` (sysid << 8 | compid) to its tracker `tr` (`SeqTracker.feed`, with the
        numbers other ids on its channel took)."""
        ch = tr.channel
        if ch is None:
            return tr.feed(seq, record, raw)
        taken, partner, mate = 0, -1, None
        last = tr.last
        if last is not None and 1 < (d := (seq - last) % 256) < LATE_WINDOW:
            taken, partner, mate = ch.taken(tr, last, d)
        out = tr.feed(seq, record, raw, taken, partner, mate)
        ch.frames = tr.at = ch.frames + 1  # the channel heard one more frame, this one of tr's
        if tr.slot < 0 or ch.ring[tr.slot] is not tr:
            ch.admit(tr, sender)
        return out

    def totals(self, sender: Sender) -> SeqTotals:
        return totals(self.senders.get(sender, {}).values())
