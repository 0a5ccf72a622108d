"""Sequence numbers of a batch of frames (`feed_batch`): what `SeqChannels.feed` gives frame by frame, with
the common step (+1 on a known counter) counted per column and every other step fed one by one.

A frame's step depends on its tracker's state alone, and on its channel's counter where other ids share
the channel (`ChannelCounter`: how many frames the channel heard, and who last used which number), so:

- rows up to each new tracker's first frame are cut into segments; that frame is fed one by one (its
  tracker made as `tracker_for` makes it, channel joined), and short segments are fed one by one too;
- in a segment, a tracker alone on its channel takes its +1 steps in bulk (last, newest, position, the
  missing slots they leave behind) and feeds the others through `SeqTracker.feed`; after a step that
  leaves the counter where it was (a duplicate, a late or unchanged frame) its next frame is fed too;
- the trackers of one channel counter are brought up to each exception's row together, so the numbers
  `ChannelCounter.taken` reads are those of that moment; a channel whose ring would change (a sender not in
  it) is fed one by one.

`Steps.code` gives each row's step (STEP_NAMES) and `Steps.tracker(row)` its tracker, for the detectors
that read them (SequenceAnomalies, ReplayedCommands).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from mavscope.analysis.sequence import LATE_WINDOW, ChannelCounter, SeqChannels, SeqTracker
from mavscope.pipeline.batch import FrameBatch

STEP_NAMES = ("next", "first", "gap", "duplicate", "unchanged", "late", "reset")
NEXT = 0
CODE = {name: k for k, name in enumerate(STEP_NAMES)}
SHORT = 48  # segments of fewer rows are fed one by one


@dataclass(slots=True)
class Steps:
    """Per row of a batch: its step's code (STEP_NAMES) and its tracker (an index into `trackers`)."""

    code: np.ndarray
    which: np.ndarray
    trackers: list[SeqTracker]
    seqs: SeqChannels  # the counters that took them

    def tracker(self, row: int) -> SeqTracker:
        return self.trackers[int(self.which[row])]


class _Feed:
    def __init__(self, seqs: SeqChannels, b: FrameBatch) -> None:
        self.seqs, self.b = seqs, b
        self.sender = b.sender
        self.seq = b.seq.astype(np.int64)
        self.code = np.zeros(b.n, np.int8)
        self.which = np.zeros(b.n, np.int32)
        self.trackers: list[SeqTracker] = []
        self.index: dict[int, int] = {}  # id(tracker) -> its place in `trackers`
        texts = b.tables.text
        # sender (16 bits), source and destination ids + 1 (23 bits each: Tables.MAX_ENDPOINTS)
        self.key = (self.sender << 46) | ((b.src.astype(np.int64) + 1) << 23) | (b.dst.astype(np.int64) + 1)
        self.ends = {int(k): (texts(int((k >> 23) & 0x7FFFFF) - 1), texts(int(k & 0x7FFFFF) - 1))
                     for k in np.unique(self.key).tolist()}

    def place(self, tr: SeqTracker) -> int:
        k = self.index.get(id(tr))
        if k is None:
            k = self.index[id(tr)] = len(self.trackers)
            self.trackers.append(tr)
        return k

    def tracker(self, key: int) -> SeqTracker:
        s = key >> 46
        return self.seqs.tracker_for((s >> 8, s & 255), self.ends[key])

    def one(self, r: int) -> None:
        """Row `r` fed as `SeqChannels.feed` feeds a frame."""
        tr = self.tracker(int(self.key[r]))
        what, _ = SeqChannels.feed_one(tr, int(self.sender[r]), int(self.seq[r]), int(self.b.record[r]),
                                       self.b.raw(r))
        self.code[r] = CODE[what]
        self.which[r] = self.place(tr)

    def run(self) -> Steps:
        n = self.b.n
        if n:
            firsts: list[int] = []  # the first row of each channel key without a tracker yet
            keys, first = np.unique(self.key, return_index=True)
            for k, r in zip(keys.tolist(), first.tolist()):
                s = k >> 46
                if self.seqs.peek((s >> 8, s & 255), self.ends[k]) is None:
                    firsts.append(r)
            lo = 0
            for r in sorted(firsts):
                self.segment(lo, r)
                self.one(r)
                lo = r + 1
            self.segment(lo, n)
        return Steps(self.code, self.which, self.trackers, self.seqs)

    def segment(self, lo: int, hi: int) -> None:
        if hi - lo < SHORT:
            for r in range(lo, hi):
                self.one(r)
            return
        rows = np.arange(lo, hi)
        keys = self.key[lo:hi]
        by_tracker: dict[int, list[np.ndarray]] = {}
        for k in np.unique(keys).tolist():
            tr = self.tracker(k)
            t = self.place(tr)
            by_tracker.setdefault(t, []).append(rows[keys == k])
        channels: dict[int, tuple[ChannelCounter, list[tuple[int, np.ndarray]]]] = {}
        for t, parts in by_tracker.items():
            got = parts[0] if len(parts) == 1 else np.sort(np.concatenate(parts))
            self.which[got] = t
            tr = self.trackers[t]
            if tr.channel is None:
                _Run(self, None, [(t, got)]).go()
            else:
                channels.setdefault(id(tr.channel), (tr.channel, []))[1].append((t, got))
        for ch, members in channels.values():
            if all(self.trackers[t].slot >= 0 and ch.ring[self.trackers[t].slot] is self.trackers[t]
                   for t, _ in members):
                _Run(self, ch, members).go()
            else:  # the ring changes on the way: one by one, in order
                for r in np.sort(np.concatenate([g for _, g in members])).tolist():
                    self.one(r)


_INF = 1 << 62  # (a row past every batch's)


class _Run:
    """The rows of trackers that share nothing but `ch` (None: one tracker alone), fed in order."""

    def __init__(self, feed: _Feed, ch: ChannelCounter | None, members: list[tuple[int, np.ndarray]]) -> None:
        self.f, self.ch = feed, ch
        self.members = members
        self.done = [0] * len(members)
        # each member's first row not taken yet (`_INF` past its last): a sync skips the members with none before
        self.next_row = [int(rows[0]) if len(rows) else _INF for _, rows in members]
        if ch is not None:
            self.rows = np.sort(np.concatenate([g for _, g in members]))
            self.base = ch.frames
        self.steps: list[np.ndarray] = []
        self.bad: list[np.ndarray] = []
        for t, rows in members:
            s = feed.seq[rows]
            tr = feed.trackers[t]
            prev = np.empty(len(rows), np.int64)
            prev[0] = -1 if tr.last is None else tr.last
            prev[1:] = s[:-1]
            d = (s - prev) % 256
            if tr.last is None:
                d[0] = 0
            self.bad.append(np.flatnonzero(d != 1))

    def at_of(self, row: int) -> int:
        """The channel's frame count once it heard row `row`."""
        return self.base + int(np.searchsorted(self.rows, row)) + 1

    def bulk(self, m: int, upto: int) -> None:
        """Member m's rows before index `upto` (all +1 steps) taken in bulk."""
        lo = self.done[m]
        if upto <= lo:
            return
        t, rows = self.members[m]
        tr = self.f.trackers[t]
        s = self.f.seq[rows[lo:upto]]
        k = upto - lo
        tr.last = int(s[-1])
        tr.newest += k
        tr.position = tr.newest
        tr.run = 0
        if tr.missing is not None:
            np.frombuffer(tr.missing, np.uint8)[(s - LATE_WINDOW) % 256] = 0
        tr.last_raw = self.f.b.raw(int(rows[upto - 1]))
        if self.ch is not None:
            tr.at = self.at_of(int(rows[upto - 1]))
        self.taken(m, upto)

    def taken(self, m: int, upto: int) -> None:
        """Member m's rows before index `upto` are taken."""
        self.done[m] = upto
        rows = self.members[m][1]
        self.next_row[m] = int(rows[upto]) if upto < len(rows) else _INF

    def sync(self, row: int) -> None:
        """Every member's rows before `row`."""
        next_row = self.next_row
        for m, (_, rows) in enumerate(self.members):
            if next_row[m] < row:
                self.bulk(m, int(np.searchsorted(rows, row)))

    def go(self) -> None:
        f = self.f
        heap: list[tuple[int, int, int]] = []  # (row, member, index among its rows)
        for m, (_, rows) in enumerate(self.members):
            if len(self.bad[m]):
                i = int(self.bad[m][0])
                heap.append((int(rows[i]), m, i))
        heapq.heapify(heap)
        while heap:
            r, m, i = heapq.heappop(heap)
            t, rows = self.members[m]
            tr = f.trackers[t]
            if self.ch is not None:
                self.sync(r)
                self.ch.frames = self.at_of(r) - 1
            else:
                self.bulk(m, i)
            what, _ = SeqChannels.feed_one(tr, int(f.sender[r]), int(f.seq[r]), int(f.b.record[r]), f.b.raw(r))
            f.code[r] = CODE[what]
            self.taken(m, i + 1)
            if i + 1 >= len(rows):
                continue
            if tr.last != int(f.seq[r]):  # the counter stayed where it was: the next step is from there
                nxt = i + 1
            else:
                bad = self.bad[m]
                j = int(np.searchsorted(bad, i, side="right"))
                if j >= len(bad):
                    continue
                nxt = int(bad[j])
            heapq.heappush(heap, (int(rows[nxt]), m, nxt))
        for m, (_, rows) in enumerate(self.members):
            self.bulk(m, len(rows))
        if self.ch is not None:
            self.ch.frames = self.base + len(self.rows)


def feed_batch(seqs: SeqChannels, b: FrameBatch) -> Steps:
    """Batch `b`'s frames to `seqs`, in capture order: each row's step (see the module docstring)."""
    return _Feed(seqs, b).run()
