"""The expert's detectors fed a batch of frames (`feed`): what `Expert.add` gives frame by frame.

- A detector that says which clean frames can change what it finds (`clean`: message names or ids, see
  `expert.Detector`) gets those rows and every row that is not clean, one by one as `Frame`s with the
  decoded fields `Expert.fields` gives; but of the rows whose only notes a native chunk gave as codes
  (`FrameBatch.coded`: a bad CRC, an unsigned frame of a signing sender), one that also says which notes
  it reads on other messages (`notes`) gets only those with such a note; one with a `signers` method
  (UnsignedCommands) is told in bulk which systems the other clean rows show signing.
- SequenceAnomalies and ReplayedCommands read the steps of the batch's sequence counters (`Steps`, one
  `SeqChannels` for the pass, shared with the statistics where `stats` runs both): the former counts
  frames per sender and records the rows that stepped back; the latter judges its command and setpoint
  rows and signature replays, and every row of a channel while it holds a copy there.
"""

from __future__ import annotations

import heapq

import numpy as np

from mavscope.analysis.commanders import COMMANDING, Fields
from mavscope.analysis.expert import Detector, Expert, SequenceAnomalies
from mavscope.analysis.replays import ReplayedCommands
from mavscope.analysis.sequence_batch import CODE, STEP_NAMES, Steps, feed_batch
from mavscope.mavlink.frame import SignatureStatus
from mavscope.pipeline.batch import NOTE_CODES, TRANSPORTS, VERDICTS, FrameBatch
from mavscope.transport.base import TRANSPORT_TLOG

_BACK = np.array([CODE["duplicate"], CODE["late"], CODE["unchanged"]], np.int8)
_REPLAY = VERDICTS.index(SignatureStatus.REPLAY.value)
_TLOG = TRANSPORTS.index(TRANSPORT_TLOG)


class _Fields:
    """The decoded fields of each row the detectors are given (`Expert.fields`), decoded once, in bulk."""

    def __init__(self, expert: Expert, b: FrameBatch) -> None:
        self.expert, self.b = expert, b
        self.got: dict[int, Fields | None] = {}

    def take(self, rows: list[int]) -> list[Fields | None]:
        """The fields of `rows` (those not decoded yet decoded together: FrameBatch.decoded)."""
        got = self.got
        new = [r for r in rows if r not in got]
        if new:
            for r, fields in zip(new, self.b.decoded(new, self.expert.decode)):
                got[r] = fields
        return [got[r] for r in rows]


def feed(expert: Expert, b: FrameBatch, steps: Steps | None = None) -> Steps:
    """Batch `b` to every detector of `expert`, in capture order; `steps`: the batch's sequence steps where
    the caller fed the counters (`StatsBuilder.add_batch`), else the expert's own counters take them."""
    if steps is None:
        steps = feed_batch(expert.seqs, b)
    if not b.n:
        return steps
    if (b.transport == _TLOG).any():
        expert.recorded = True
    fields = _Fields(expert, b)
    for d in expert.detectors:
        if isinstance(d, SequenceAnomalies):
            _sequence(d, b, steps)
        elif isinstance(d, ReplayedCommands):
            _replays(d, b, steps)
        else:
            _generic(d, b, fields)
    return steps


def _generic(d: Detector, b: FrameBatch, fields: _Fields) -> None:
    wanted = getattr(d, "clean", None)
    if wanted is None:
        rows = np.arange(b.n)
    else:
        given = ~b.clean | b.of_messages(wanted)
        noted: frozenset[str] | None = getattr(d, "notes", None)
        if noted is not None:  # of the rows whose notes are codes, those of its messages and notes alone
            bits = sum(NOTE_CODES.get(code, 0) for code in noted)
            given &= (b.coded == 0) | (b.coded & bits != 0) | b.of_messages(wanted)
        rows = np.flatnonzero(given)
        signers = getattr(d, "signers", None)
        if signers is not None:
            quiet = ~given & b.signed
            if quiet.any():
                signers(np.unique(b.sysid[quiet]).tolist())
    listed = rows.tolist()
    decoded = fields.take(listed)  # (before the Frames: a row without one is decoded without making it)
    for f, values in zip(b.frames(listed), decoded):
        d.add(f, values)


def _sequence(d: SequenceAnomalies, b: FrameBatch, steps: Steps) -> None:
    d.seqs = steps.seqs
    sender = b.sender
    counts = np.bincount(sender, minlength=1 << 16)
    for s in np.flatnonzero(counts).tolist():
        d.counts[(s >> 8, s & 255)] += int(counts[s])
    for r in np.flatnonzero(np.isin(steps.code, _BACK)).tolist():
        s = int(sender[r])
        d.event((s >> 8, s & 255), STEP_NAMES[steps.code[r]], int(b.record[r]), b.msgname(r))


def _replays(d: ReplayedCommands, b: FrameBatch, steps: Steps) -> None:
    d.seqs = steps.seqs
    candidate = b.of_messages(COMMANDING) | (b.verdict == _REPLAY)
    heap = np.flatnonzero(candidate).tolist()  # ascending: a heap
    held = {id(tr) for tr in steps.trackers} & d.held.keys()
    for t, tr in enumerate(steps.trackers):
        if id(tr) in held:
            for r in np.flatnonzero(steps.which == t).tolist():
                heapq.heappush(heap, r)
    done = -1
    pushed: dict[int, int] = {}  # channel -> the row after which its rows are all in the heap
    while heap:
        r = heapq.heappop(heap)
        if r <= done:
            continue
        done = r
        tr = steps.tracker(r)
        key = id(tr)
        was_held = key in d.held
        if not candidate[r] and not was_held:
            continue  # a row of a channel whose copies were judged since
        d.judge(b.frame(r), STEP_NAMES[steps.code[r]], key)
        if not was_held and key in d.held:  # the channel holds a copy now: its later rows are judged too
            channel = int(steps.which[r])
            if pushed.get(channel, r + 1) > r:  # (once a channel's later rows are in the heap, they stay)
                pushed[channel] = r
                for later in np.flatnonzero(steps.which[r + 1:] == channel).tolist():
                    heapq.heappush(heap, r + 1 + later)
