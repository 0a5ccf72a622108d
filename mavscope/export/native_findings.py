"""The findings of the native batch source: the analyses of `pure.Analyses`, fed each window of frames in
the state the pure source's one pass would leave them, without a Python Frame for every frame.

A window is a chunk of frames the C walker took (clean: good CRC, no note, plaintext, no verdict but
`no-key`) and the frames the Python pipeline made of the records handed back among them, in capture order.
What each analysis does with a frame is kept exactly; what differs is how often Python runs:

- Frames a detector looks at (the messages the expert decodes, HEARTBEATs, the object and parameter
  trackers' messages) and every handed-back frame are built as Frames and given to the analyses one by
  one, in capture order (each analysis is an object of its own: each sees its frames in order).
- Sequence numbers, which the expert's `SequenceAnomalies` (per sender and channel) and
  `ReplayedCommands` (per sender) follow on every frame, are stepped from the columns: runs of frames each
  one after the other (+1) are taken in bulk (`SeqTracker.skip`, exact, dropped missing slots included),
  every other frame (a gap, a repeat, the first of a run, a frame a detector must judge) is fed one by one.
- The audit's per-frame parts on clean frames are a first plaintext per (system, message) (a
  `setdefault` at the first one) and the signing streams' target frames (`Targets.add_run`, by count);
  `UnsignedCommands` needs only which systems sign; the object and parameter trackers' activity clock
  counts every frame (`tick`), set before each frame they are given.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mavscope.analysis.expert import COMMANDING, Detector, ReplayedCommands, SequenceAnomalies, UnsignedCommands
from mavscope.analysis.objects.tracker import TRACKED_MESSAGES
from mavscope.analysis.params.tracker import MESSAGES as PARAM_MESSAGES
from mavscope.analysis.sequence import Endpoints, SeqTracker, endpoints
from mavscope.endpoint import Endpoint
from mavscope.export.native_columns import Chunk, decoded, message_plan
from mavscope.export.pure import Analyses
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import CrcStatus, Frame, Signature, new_frame

EVENTS = frozenset({"duplicate", "late", "unchanged"})  # SequenceAnomalies.event keeps these
_TRANSPORT = {1: "udp", 2: "tlog"}  # columns.h MS_TRANSPORT_*


def _one(detectors: Sequence[Detector], kind: type) -> Detector:
    found = [d for d in detectors if isinstance(d, kind)]
    if len(found) != 1:
        raise ValueError(f"the native source feeds one {kind.__name__}, not {len(found)}")
    return found[0]


def _reads(clean: frozenset[str | int] | None) -> Callable[[MessageDef], bool]:
    """Whether a detector with `Detector.clean` reads the clean frames of a message."""
    return lambda md: clean is None or md.name in clean or md.id in clean


def _nth(w: Window, rows: list[int]) -> Callable[[int], Frame]:
    return lambda k: w.frame(rows[k])


def _groups(keys: np.ndarray) -> list[np.ndarray]:
    """Row positions per distinct key, each group ascending, the groups in the order of their first row."""
    if not len(keys):
        return []
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    cut = np.flatnonzero(sorted_keys[1:] != sorted_keys[:-1]) + 1
    groups = np.split(order, cut)
    groups.sort(key=lambda g: int(g[0]))
    return groups


def window_rows(n: int, pos: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """The rows, in capture order, of `n` native frames and of the handed-back frames, the j-th of which
    came after `pos[j]` native frames: (rows of the native ones, rows of the handed-back ones)."""
    at = np.asarray(pos, np.int64)
    return np.arange(n) + np.searchsorted(at, np.arange(n), side="right"), at + np.arange(len(at))


class Window:
    """One window: the native rows of chunk `c` and the handed-back frames `py`, the j-th of them after
    `pos[j]` native rows, as rows in capture order."""

    def __init__(self, c: Chunk, py: list[Frame], pos: Sequence[int], messages: Sequence[MessageDef],
                 ends: Sequence[Endpoint]) -> None:
        self.c, self.py, self.messages, self.ends = c, py, messages, ends
        n, p = c.n, len(py)
        self.size = n + p
        self.gn, self.gp = window_rows(n, pos)  # the row of each native and of each handed-back frame
        self.native = np.ones(self.size, np.bool_)
        self.native[self.gp] = False
        self.at = np.empty(self.size, np.int64)  # the row's index among the native frames or among `py`
        self.at[self.gn] = np.arange(n)
        self.at[self.gp] = np.arange(p)
        self.sender = self._join(c.sysid.astype(np.int64) << 8 | c.compid, [f.sysid << 8 | f.compid for f in py])
        self.seq = self._join(c.seq.astype(np.int64), [f.seq for f in py])
        self.record = self._join(c.record, [f.record for f in py]).tolist()
        self.built: dict[int, Frame] = {}

    def _join(self, native: np.ndarray, py: list[int]) -> np.ndarray:
        out = np.empty(self.size, np.int64)
        out[self.gn] = native
        out[self.gp] = np.asarray(py, np.int64)
        return out

    def native_rows(self, mask: np.ndarray) -> np.ndarray:
        """The rows of the native frames where `mask` (per native frame) is set."""
        return self.gn[mask]

    def message_of_row(self) -> list[int]:
        """Per row, the table position of a native frame's message (-1 for a handed-back frame)."""
        out = np.full(self.size, -1, np.int64)
        out[self.gn] = self.c.message
        rows: list[int] = out.tolist()
        return rows

    def build(self, rows: np.ndarray) -> None:
        """Frames of the native rows `rows`, as the Python dissector makes them (kept for `frame`)."""
        c = self.c
        if self.built:
            rows = rows[[r not in self.built for r in rows.tolist()]]
        idx = self.at[rows]
        if not len(idx):
            return
        raw, at, end = c.raw, c.raw_at[idx].tolist(), c.raw_at[idx + 1].tolist()
        ends = list(self.ends) + [None]  # an id of -1 (no endpoint): the None at the end
        messages = self.messages
        times = [t if ok else None for t, ok in zip(c.time[idx].tolist(), c.time_ok[idx].tolist())]
        transports = [_TRANSPORT[t] for t in c.transport[idx].tolist()]
        signed = c.signed[idx].tolist()
        cols = [a[idx].tolist() for a in (c.record, c.index, c.offset, c.version, c.len, c.iflags, c.cflags, c.seq,
                                           c.sysid, c.compid, c.msgid, c.crc, c.sig_link, c.sig_time)]
        built = self.built
        for (row, a, b, time, transport, src, dst, message, is_signed, record, index, offset, version, length,
             iflags, cflags, seq, sysid, compid, msgid, crc, link, stamp) in zip(
                rows.tolist(), at, end, times, transports, c.src[idx].tolist(), c.dst[idx].tolist(),
                c.message[idx].tolist(), signed, *cols):
            r = raw[a:b]
            built[row] = new_frame(
                record, index, time, transport, ends[src], ends[dst], offset, r, version,
                length, iflags, cflags, seq, sysid, compid, msgid, crc, CrcStatus.OK, messages[message],
                Signature(link, stamp, r[-6:]) if is_signed else None, (), None)

    def frame(self, row: int) -> Frame:
        if not self.native[row]:
            return self.py[int(self.at[row])]
        f = self.built.get(row)
        if f is None:
            self.build(np.array([row]))
            f = self.built[row]
        return f

    def raw(self, row: int) -> bytes:
        if not self.native[row]:
            return self.py[int(self.at[row])].raw
        return self.c.raw_of(int(self.at[row]))


def run_tracker(tr: SeqTracker, rows: np.ndarray, seqs: np.ndarray, records: list[int],
                must: np.ndarray | None, raw: Callable[[int], bytes] | None) -> list[tuple[int, str, int]]:
    """Step `tr` through its frames `rows` (numbers `seqs`), as feeding each would: runs of +1 steps in bulk,
    the others (and the rows `must` marks) fed one by one. (row, step, position) of those fed."""
    m = len(rows)
    s = seqs.tolist()
    special = np.ones(m, np.bool_)
    if m > 1:
        special[1:] = (np.diff(seqs) % 256) != 1
    if must is not None:
        special |= must
    stops = np.flatnonzero(special).tolist()
    out: list[tuple[int, str, int]] = []
    i = k = 0
    while i < m:
        if special[i] or tr.last is None or (s[i] - tr.last) % 256 != 1:
            row = int(rows[i])
            step, _ = tr.feed(s[i], records[row], raw(row) if raw is not None else None)
            out.append((row, step, tr.position))
            i += 1
            continue
        while k < len(stops) and stops[k] <= i:
            k += 1
        j = stops[k] if k < len(stops) else m
        tr.skip(j - i, raw(int(rows[j - 1])) if raw is not None else None)
        i = j
    return out


class NativeFeed:
    """Feeds `analyses` window by window (see the module docstring)."""

    def __init__(self, analyses: Analyses, dialect: Dialect, messages: Sequence[MessageDef]) -> None:
        self.a = analyses
        self.dialect = dialect
        self.payload_rows: Sequence[tuple[int, Any, Any, int]] = ()  # the current window's (Columns.take)
        ex = analyses.expert
        self.seq: SequenceAnomalies = _one(ex.detectors, SequenceAnomalies)  # type: ignore[assignment]
        self.replay: ReplayedCommands = _one(ex.detectors, ReplayedCommands)  # type: ignore[assignment]
        self.unsigned: UnsignedCommands = _one(ex.detectors, UnsignedCommands)  # type: ignore[assignment]
        self.others = [d for d in ex.detectors if d is not self.seq and d is not self.replay]
        self.messages = messages
        self.commanding = self._mask(lambda md: md.name in COMMANDING)
        # per message of the table: the detectors its clean frames go to (Detector.clean; all without it)
        wanted = [self._mask(_reads(getattr(d, "clean", None))) for d in self.others]
        self.dispatch = [tuple(d for d, m in zip(self.others, wanted) if m[k]) for k in range(len(messages))]
        self.detected = np.array([bool(ds) for ds in self.dispatch], np.bool_)
        self.objects_msgs = self._mask(lambda md: md.name in TRACKED_MESSAGES)
        self.params_msgs = self._mask(lambda md: md.name in PARAM_MESSAGES)
        self.seen = 0  # frames of the capture before the current window
        self.channels: dict[Endpoints, int] = {}
        self.channel_ends: list[Endpoints] = []
        self.trackers: dict[tuple[int, int], SeqTracker] = {}  # (sender, channel) -> its SequenceAnomalies tracker

    def _mask(self, test: Callable[[MessageDef], bool]) -> np.ndarray:
        """Per message of the table, whether `test` holds."""
        return np.array([test(md) for md in self.messages], np.bool_)

    def window(self, c: Chunk, py: list[Frame], pos: Sequence[int], ends: Sequence[Endpoint],
               rows: Sequence[tuple[int, Any, Any, int]]) -> None:
        """One window: chunk `c`, the handed-back frames `py` (after `pos[j]` native ones), the chunk's
        endpoints and its message rows (`_native.Columns.take`: position, payload rows, frames, count)."""
        w = Window(c, py, pos, self.messages, ends)
        self.payload_rows = rows
        if not w.size:
            return
        by_msg = c.message
        w.build(w.native_rows((self.detected | self.commanding | self.objects_msgs | self.params_msgs)[by_msg]))
        self._detectors(w)
        self._sequences(w, ends)
        self._replays(w)
        self._audit(w)
        self._objects(w)
        self.seen += w.size

    def _in_order(self, w: Window, native: np.ndarray) -> list[int]:
        """The rows of the native frames where `native` is set and of every handed-back frame, in order."""
        return np.sort(np.concatenate([w.native_rows(native), w.gp])).tolist()

    def _fields(self, w: Window) -> dict[int, dict[str, object]]:
        """`Expert.fields` of the native rows that have any (a message the expert decodes), by row: the
        payload rows of messages of scalar fields decoded in bulk, the others by the message's decoder."""
        out: dict[int, dict[str, object]] = {}
        decode = self.a.expert.decode
        for position, rows, frames, count in self.payload_rows:
            md = self.messages[position]
            if md.name not in decode or not self.detected[position]:
                continue
            at = np.frombuffer(frames, np.uint32, count=count)
            plan = message_plan(md, self.dialect)
            if plan.simple:
                out.update(zip(w.gn[at].tolist(), decoded(plan, rows, count)))
            else:
                payload = w.c.payload_of
                out.update((r, md.decode(payload(i))) for r, i in zip(w.gn[at].tolist(), at.tolist()))
        return out

    def _detectors(self, w: Window) -> None:
        fields_of = self.a.expert.fields
        others, dispatch = self.others, self.dispatch
        message = w.message_of_row()
        fields = self._fields(w)
        for row in self._in_order(w, self.detected[w.c.message]):
            f = w.frame(row)
            m = message[row]
            if m >= 0:
                fs = fields.get(row)
                for d in dispatch[m]:
                    d.add(f, fs)
            else:
                fs = fields_of(f)
                for d in others:
                    d.add(f, fs)
        c = w.c
        self.unsigned.signers(np.unique(c.sysid[c.signed]).tolist())

    def _channel(self, ends: Endpoints) -> int:
        k = self.channels.get(ends)
        if k is None:
            k = self.channels[ends] = len(self.channel_ends)
            self.channel_ends.append(ends)
        return k

    def _sequences(self, w: Window, ends: Sequence[Endpoint]) -> None:
        c, seq = w.c, self.seq
        groups = _groups(w.sender)
        seq.counts.update({(int(w.sender[g[0]]) >> 8, int(w.sender[g[0]]) & 255): len(g) for g in groups})
        chan = np.empty(w.size, np.int64)
        if c.n:
            pair = (c.src.astype(np.int64) + 1) << 32 | (c.dst.astype(np.int64) + 1)  # ids from -1 up
            distinct, inverse = np.unique(pair, return_inverse=True)

            def text(k: int) -> str:
                return ends[k].text if k >= 0 else ""

            ids = [self._channel((text((p >> 32) - 1), text((p & 0xFFFFFFFF) - 1))) for p in distinct.tolist()]
            chan[w.gn] = np.asarray(ids, np.int64)[inverse.reshape(-1)]
        for j, f in enumerate(w.py):
            chan[w.gp[j]] = self._channel(endpoints(f))
        key = w.sender << 32 | chan
        trackers: list[SeqTracker] = []
        index_of: dict[int, int] = {}  # id of a tracker -> its position in `trackers` (channels may share one)
        per_row = np.empty(w.size, np.int64)
        for g in _groups(key):
            sender, channel = int(w.sender[g[0]]), int(chan[g[0]])
            tr = self.trackers.get((sender, channel))
            if tr is None:
                tr = self.trackers[(sender, channel)] = seq.seqs.tracker_for((sender >> 8, sender & 255),
                                                                             self.channel_ends[channel])
            k = index_of.get(id(tr))
            if k is None:
                k = index_of[id(tr)] = len(trackers)
                trackers.append(tr)
            per_row[g] = k
        events: list[tuple[int, str]] = []
        for g in _groups(per_row):
            tr = trackers[int(per_row[g[0]])]
            events += [(row, step) for row, step, _ in run_tracker(tr, g, w.seq[g], w.record, None, w.raw)
                       if step in EVENTS]
        events.sort()
        for row, step in events:
            s = int(w.sender[row])
            seq.event((s >> 8, s & 255), step, w.record[row])

    def _replays(self, w: Window) -> None:
        judged = ~w.native
        judged[w.native_rows(self.commanding[w.c.message])] = True
        trackers = self.replay.trackers
        steps: list[tuple[int, str, int]] = []
        for g in _groups(w.sender):
            s = int(w.sender[g[0]])
            link = (s >> 8, s & 255)
            tr = trackers.get(link)
            if tr is None:
                tr = trackers[link] = SeqTracker()
            steps += [x for x in run_tracker(tr, g, w.seq[g], w.record, judged[g], None) if judged[x[0]]]
        steps.sort()
        judge = self.replay.judge
        for row, step, position in steps:
            judge(w.frame(row), step, position)

    def _audit(self, w: Window) -> None:
        c, audit = w.c, self.a.audit
        plain = audit.keystreams.plain
        events: list[tuple[int, int]] = [(int(r), -1) for r in w.gp]  # (row, native frame or -1: handed back)
        v2 = np.flatnonzero(c.version == 2)
        if len(v2):
            keys = c.sysid[v2].astype(np.int64) << 32 | c.msgid[v2]
            distinct, first = np.unique(keys, return_index=True)
            for k, i in zip(distinct.tolist(), v2[first].tolist()):
                if (k >> 32, k & 0xFFFFFFFF) not in plain:
                    events.append((int(w.gn[i]), i))
        events.sort()
        for row, i in events:
            if i < 0:
                audit.add_untargeted(w.frame(row))
            else:
                f_sysid, msgid = int(c.sysid[i]), int(c.msgid[i])
                md = self.messages[int(c.message[i])]
                plain.setdefault((f_sysid, msgid), (int(c.record[i]), c.payload_of(i).ljust(md.length, b"\x00")))
        signed = [r for r, f in zip(w.gp.tolist(), w.py) if f.signature is not None and f.crc_status is CrcStatus.OK]
        rows = np.sort(np.concatenate([w.native_rows(c.signed), np.asarray(signed, np.int64)]))
        if not len(rows):
            return
        link = np.empty(w.size, np.int64)
        link[w.gn] = c.sig_link
        for j, f in enumerate(w.py):
            link[w.gp[j]] = f.signature.link_id if f.signature is not None else 0
        stream = w.sender[rows] << 8 | link[rows]
        for g in _groups(stream):
            s = int(stream[g[0]])
            members = rows[g].tolist()
            audit.targets.add_run((s >> 16, (s >> 8) & 255, s & 255), len(g), _nth(w, members))

    def _objects(self, w: Window) -> None:
        objects, params = self.a.objects, self.a.params
        inner = params.objects
        messages = w.c.message
        for row in self._in_order(w, self.objects_msgs[messages]):
            objects.ctx.tick = self.seen + row
            objects.feed(w.frame(row))
            Analyses.took(objects)
        for row in self._in_order(w, self.params_msgs[messages]):
            inner.ctx.tick = self.seen + row
            params.feed(w.frame(row))
        objects.ctx.tick = inner.ctx.tick = self.seen + w.size
        c = w.c
        last = -1
        if c.n and c.time_ok.any():
            last = int(w.gn[np.flatnonzero(c.time_ok)[-1]])
        for r, f in zip(w.gp.tolist(), w.py):
            if r > last and f.time is not None and f.msgdef is not None and f.crc_status is CrcStatus.OK:
                last = r
        if last >= 0:
            params.now = w.frame(last).time if not w.native[last] else float(c.time[w.at[last]])
