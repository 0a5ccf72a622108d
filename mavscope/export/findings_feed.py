"""The findings of the native batch source: the analyses of `pure.Analyses`, fed each window of frames in
the state the pure source's one pass would leave them, without a Python Frame for every frame.

The expert's detectors (`stats`' findings) are not fed here: the export gives them each window as a
`FrameBatch` (analysis.expert_batch, as `stats` does). What is fed here, window by window, is the audit (with
its detection rules), the object tracker and the parameter tracker.

A window is a chunk of frames the C walker took (clean: good CRC, no note, plaintext, no verdict but
`no-key`) and the frames the Python pipeline made of the records handed back among them, in capture order.
What each analysis does with a frame is kept exactly; what differs is how often Python runs:

- Frames of the messages the object and parameter trackers read, and every handed-back frame, are built as
  Frames and given to them one by one, in capture order; but not the HEARTBEATs that cannot change what
  the parameter tracker holds (`NativeFeed._quiet_heartbeats`).
- The detection rules (mavscope.rules) are given, in capture order, the frames of the messages they read and,
  where they read them, every signed frame (`RuleEngine.reads`), and every handed-back frame.
- The audit's per-frame parts on clean frames are a first plaintext per (system, message) (a
  `setdefault` at the first one) and the signing streams' target frames (`Targets.add_run`, by count);
  the object and parameter trackers' activity clock counts every frame (`tick`), set before each frame
  they are given.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mavscope.analysis.objects.tracker import TRACKED_MESSAGES
from mavscope.analysis.params.tracker import MAV_AUTOPILOT_INVALID, MAV_AUTOPILOT_PX4, MAV_TYPE_GCS
from mavscope.analysis.params.tracker import MESSAGES as PARAM_MESSAGES
from mavscope.endpoint import Endpoint
from mavscope.export.command_keys import CommandKeys, payload_rows
from mavscope.export.pure import Analyses
from mavscope.mavlink.dialect import MessageDef, char_text
from mavscope.mavlink.frame import CrcStatus, Frame, Signature, SignatureStatus, new_frame
from mavscope.native.chunk import Chunk
from mavscope.native.core import COLUMN_TRANSPORTS
from mavscope.pipeline.dissect import Anomaly
from mavscope.security.downgrade import Downgrades, signs, unsigned
from mavscope.security.stage import RADIO_STATUS

_TRANSPORT = {k: t for k, t in enumerate(COLUMN_TRANSPORTS) if t is not None}  # the transport column's codes


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


def _param_value_layout(position: int, md: MessageDef) -> tuple[int, int, int, int, int, int] | None:
    """PARAM_VALUE's position in the table, length and field offsets where its fields are common.xml's
    (a dialect that redefines them: None, and its frames are built and given to `feed`)."""
    want = {"param_value": ("float", 0), "param_count": ("uint16_t", 0), "param_id": ("char", 16),
            "param_type": ("uint8_t", 0)}
    got = {n: md.field(n) for n in want}
    offsets: list[int] = []
    for n, (kind, count) in want.items():
        fd = got[n]
        if fd is None or fd.type != kind or fd.array_length != count:
            return None
        offsets.append(fd.offset)
    value, count_at, id_at, type_at = offsets
    return (position, md.length, value, count_at, id_at, type_at)


def _times(c: Chunk, idx: np.ndarray) -> list[float | None]:
    """The capture times of chunk rows `idx` as a Frame holds them (None where the capture gave none)."""
    return [t if ok else None for t, ok in zip(c.time[idx].tolist(), c.time_ok[idx].tolist())]


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
        self.built: dict[int, Frame] = {}

    def _join(self, native: np.ndarray, py: list[int]) -> np.ndarray:
        """Per row: `native`'s value for a native frame, `py`'s for a handed-back one."""
        if not py:
            return native  # the rows are the native frames
        out = np.empty(self.size, np.int64)
        out[self.gn] = native
        out[self.gp] = np.asarray(py, np.int64)
        return out

    def native_rows(self, mask: np.ndarray) -> np.ndarray:
        """The rows of the native frames where `mask` (per native frame) is set."""
        return self.gn[mask]

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
        times = _times(c, idx)
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



class NativeFeed:
    """Feeds the audit, object and parameter analyses of `analyses` window by window (see the module
    docstring); the expert's detectors are fed by the export's batches (native.export)."""

    def __init__(self, analyses: Analyses, messages: Sequence[MessageDef]) -> None:
        self.a = analyses
        self.messages = messages
        self.objects_msgs = self._mask(lambda md: md.name in TRACKED_MESSAGES)
        self.params_msgs = self._mask(lambda md: md.name in PARAM_MESSAGES)
        self.commands = CommandKeys(messages)  # whether the audit's command matcher could give up a command
        self.signing = np.zeros(1 << 16, np.bool_)  # per sender (sysid << 8 | compid): Downgrades.signers
        self.seen = 0  # frames of the capture before the current window
        # HEARTBEAT's table position and the offsets of the two fields the parameter tracker reads
        self.heartbeat: tuple[int, int, int, int] | None = None  # (position, length, type, autopilot)
        # PARAM_VALUE's table position, length and the offsets of the fields the parameter tracker reads
        self.param_value: tuple[int, int, int, int, int, int] | None = None  # (position, length, and the value,
        self.rules = analyses.audit_pass.rules  # the detection rules: the frames they read (RuleEngine.reads)
        ids, self.rules_signed = self.rules.reads if self.rules is not None else (frozenset(), False)
        self.rules_msgs = None if ids is None else self._mask(lambda md: md.id in ids)
        for k, md in enumerate(messages):  # count, id and type offsets)
            if md.name == "HEARTBEAT":
                t, a = md.field("type"), md.field("autopilot")
                if t is not None and a is not None and t.size == a.size == 1:
                    self.heartbeat = (k, md.length, t.offset, a.offset)
            elif md.name == "PARAM_VALUE" and md.name not in TRACKED_MESSAGES:
                self.param_value = _param_value_layout(k, md)

    def _mask(self, test: Callable[[MessageDef], bool]) -> np.ndarray:
        """Per message of the table, whether `test` holds."""
        return np.array([test(md) for md in self.messages], np.bool_)

    def window(self, c: Chunk, py: list[Frame], pos: Sequence[int], ends: Sequence[Endpoint],
               parts: Sequence[tuple[int, Any, Any, int]], anomalies: Sequence[tuple[int, Anomaly]] = ()) -> None:
        """One window: chunk `c`, the handed-back frames `py` (after `pos[j]` native ones), the chunk's
        endpoints and its payload rows (`_native.Columns.take`: position, rows, frames, count per message),
        and the window's anomalies (each after so many of `py`: the audit takes them in that order, as the
        pure source gives them)."""
        w = Window(c, py, pos, self.messages, ends)
        if not w.size:
            for _, item in anomalies:
                self.a.anomaly(item)
            return
        params = self.params_msgs[c.message]
        params[self._quiet_heartbeats(w, parts)] = False
        given, reports = self._param_values(w, parts)
        build = self.objects_msgs[c.message] | params
        build[given] = False
        w.build(w.native_rows(build))
        self._audit(w, anomalies)
        self._downgrades(w)
        self._rules(w)
        if not self.commands.may_give_up:
            self.commands.window(c, py, parts)
        self._objects(w, params, reports)
        self.seen += w.size

    def _param_values(self, w: Window, parts: Sequence[tuple[int, Any, Any, int]],
                      ) -> tuple[np.ndarray, dict[int, tuple[Any, ...]]]:
        """The native PARAM_VALUEs of the window, read from their payload rows (no Frame built): their
        index in the chunk, and their row -> the arguments of `ParamTracker.param_value` as its `feed`
        finds them."""
        if self.param_value is None:
            return np.empty(0, np.int64), {}
        position, length, v_at, n_at, id_at, t_at = self.param_value
        got = payload_rows(parts, position, length)
        if got is None:
            return np.empty(0, np.int64), {}
        at, payload = got
        raw = np.ascontiguousarray(payload[:, v_at:v_at + 4]).view("V4").ravel().tolist()
        total = np.ascontiguousarray(payload[:, n_at:n_at + 2]).view("<u2").ravel().tolist()
        ids = np.ascontiguousarray(payload[:, id_at:id_at + 16]).view("V16").ravel().tolist()
        kind = payload[:, t_at].tolist()
        c, ends = w.c, w.ends
        times = _times(c, at)
        links = [ends[s].text if s >= 0 else _TRANSPORT[t]
                 for s, t in zip(c.src[at].tolist(), c.transport[at].tolist())]
        no_key = SignatureStatus.NO_KEY.value  # a native frame's only verdict (the tracker's `_verdict`)
        verdicts = [no_key if s else "unsigned" for s in c.signed[at].tolist()]
        names: dict[bytes, str] = {}
        out: dict[int, tuple[Any, ...]] = {}
        for row, sysid, compid, record, when, link, verdict, pid, value, ptype, n in zip(
                w.gn[at].tolist(), c.sysid[at].tolist(), c.compid[at].tolist(), c.record[at].tolist(), times, links,
                verdicts, ids, raw, kind, total):
            name = names.get(pid)
            if name is None:
                name = names[pid] = char_text(pid)
            out[row] = ((sysid, compid), record, when, link, verdict, name, value, ptype, n)
        return at, out

    def _quiet_heartbeats(self, w: Window, parts: Sequence[tuple[int, Any, Any, int]]) -> np.ndarray:
        """The native HEARTBEATs the parameter tracker need not be given (their index in the chunk).

        A HEARTBEAT tells the tracker one thing, the parameter encoding of its system: none (autopilot
        INVALID or a GCS), or PX4's bytewise, or C-cast, set unless an AUTOPILOT_VERSION set it (which then
        stays); its clock (`tick`) is set before each frame given and its `now` at the window's end. So a
        HEARTBEAT that says none changes nothing, and one that says what the previous HEARTBEAT of its system
        in this window said changes nothing either, unless a handed-back frame of that system (which may be a
        HEARTBEAT saying something else) came between: those are left out, every other one is given."""
        if self.heartbeat is None:
            return np.empty(0, np.int64)
        position, length, t_at, a_at = self.heartbeat
        got = payload_rows(parts, position, length)
        if got is None:
            return np.empty(0, np.int64)
        at, payload = got
        count = len(at)
        autopilot, kind = payload[:, a_at], payload[:, t_at]
        says = np.where((autopilot == MAV_AUTOPILOT_INVALID) | (kind == MAV_TYPE_GCS), 0,
                        np.where(autopilot == MAV_AUTOPILOT_PX4, 1, 2))
        # per system, in capture order: what each HEARTBEAT says, and each handed-back frame as a word of its own
        rows_of = np.concatenate([w.gn[at], w.gp])
        system = np.concatenate([w.c.sysid[at].astype(np.int64), np.asarray([f.sysid for f in w.py], np.int64)])
        word = np.concatenate([says, -1 - np.arange(len(w.py), dtype=np.int64)])
        order = np.lexsort((rows_of, system))
        system, word = system[order], word[order]
        same = np.zeros(len(order), np.bool_)
        same[1:] = (system[1:] == system[:-1]) & (word[1:] == word[:-1])
        quiet = (word == 0) | same
        native = order < count
        return at[order[quiet & native]]

    def _in_order(self, w: Window, native: np.ndarray) -> list[int]:
        """The rows of the native frames where `native` is set and of every handed-back frame, in order."""
        return np.sort(np.concatenate([w.native_rows(native), w.gp])).tolist()

    def _audit(self, w: Window, anomalies: Sequence[tuple[int, Anomaly]]) -> None:
        c, audit = w.c, self.a.audit
        later = iter(anomalies)
        after, anomaly = next(later, (-1, None))  # (handed-back frames before it, the anomaly)
        j = 0  # the handed-back frames given so far
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
                while anomaly is not None and after <= j:
                    audit.anomaly(anomaly)
                    after, anomaly = next(later, (-1, None))
                audit.add_untargeted(w.frame(row))
                j += 1
            else:
                f_sysid, msgid = int(c.sysid[i]), int(c.msgid[i])
                md = self.messages[int(c.message[i])]
                plain.setdefault((f_sysid, msgid), (int(c.record[i]), c.payload_of(i).ljust(md.length, b"\x00")))
        while anomaly is not None:
            audit.anomaly(anomaly)
            after, anomaly = next(later, (-1, None))
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

    def _rules(self, w: Window) -> None:
        """The detection rules: the window's frames they read, in capture order."""
        if self.rules is None:
            return
        c = w.c
        mask = np.ones(c.n, np.bool_) if self.rules_msgs is None else self.rules_msgs[c.message]
        if self.rules_signed:
            mask = mask | c.signed.astype(np.bool_)
        w.build(w.native_rows(mask))
        add = self.rules.add
        for row in self._in_order(w, mask):
            add(w.frame(row))

    def _downgrades(self, w: Window) -> None:
        """`Downgrades.add` for every frame of the window, in bulk: the rows of senders not yet seen signing,
        each up to its first signing frame (`signs`: a native signed frame always is, the stage checked no
        signature of it); the unsigned ones but RADIO_STATUS counted per sender, the first listed (as many
        as `room` allows, EARLY_TOTAL's share taken in capture order), no Frame built."""
        d = self.a.audit_pass.downgrades
        c, py = w.c, w.py
        sender = w.sender
        live = np.flatnonzero(~self.signing[sender])  # rows of senders not yet seen signing
        if not len(live):
            return
        native = w.native[live]
        sign, plain = np.empty(len(live), np.bool_), np.empty(len(live), np.bool_)
        i = w.at[live[native]]
        sign[native] = c.signed[i] & (c.version[i] == 2)
        plain[native] = ~sign[native] & (c.msgid[i] != RADIO_STATUS)
        if not native.all():  # the handed-back frames among them
            fs = [py[j] for j in w.at[live[~native]].tolist()]
            sign[~native] = [signs(f) for f in fs]
            plain[~native] = [unsigned(f) and f.msgid != RADIO_STATUS for f in fs]
        who = sender[live]
        first = np.full(1 << 16, w.size, np.int64)  # each sender's first signing row of the window
        if sign.any():
            signers, at = np.unique(who[sign], return_index=True)
            first[signers] = live[sign][at]
        early = live[plain & (live < first[who])]
        if len(early):
            self._early(d, w, early)
        if sign.any():
            self.signing[signers] = True
            d.signers.update((int(s) >> 8, int(s) & 255) for s in signers.tolist())

    def _early(self, d: Downgrades, w: Window, early: np.ndarray) -> None:
        """Rows `early` (ascending) of senders not yet signing, unsigned, before their sender's first signing
        frame: counted and listed into `d` (Downgrades) as its `add` would."""
        who = w.sender[early]
        counts = np.bincount(who, minlength=1 << 16)
        present = np.flatnonzero(counts)  # the senders, ascending
        native = w.native[early]
        v1_rows = np.empty(len(early), np.bool_)
        v1_rows[native] = w.c.version[w.at[early[native]]] == 1
        v1_rows[~native] = [w.py[j].version == 1 for j in w.at[early[~native]].tolist()]
        v1 = np.bincount(who[v1_rows], minlength=1 << 16)[present].tolist()
        total = counts[present].tolist()
        keys = [(s >> 8, s & 255) for s in present.tolist()]
        order = range(len(keys))
        if any(k not in d.early for k in keys):  # senders first heard here: in the order first heard, as `add`
            _, first_at = np.unique(who, return_index=True)
            order = np.argsort(first_at, kind="stable").tolist()
        rooms = [d.room(k) for k in keys]
        listed: dict[int, list[tuple[int, int, int, str]]] = {}
        if any(rooms):
            group = np.searchsorted(present, who)  # each row's sender, as its place in `present`
            by = np.argsort(group, kind="stable")  # rank of each row among its sender's
            starts = np.concatenate([[0], np.cumsum(total)[:-1]]).astype(np.int64)
            rank = np.empty(len(early), np.int64)
            rank[by] = np.arange(len(early)) - starts[group[by]]
            kept = np.flatnonzero(rank < np.asarray(rooms, np.int64)[group])[:d.room()]
            for j in kept.tolist():
                listed.setdefault(int(group[j]), []).append(self._listed(w, int(early[j])))
        for g in order:
            d.unsigned_run(keys[g], v1[g], total[g] - v1[g], listed.get(g, ()))

    def _listed(self, w: Window, row: int) -> tuple[int, int, int, str]:
        """(version, record, index, message name) of a row, as `Downgrades.add` lists a frame."""
        if not w.native[row]:
            f = w.py[int(w.at[row])]
            return (f.version, f.record, f.index, f.msgname or str(f.msgid))
        c, i = w.c, int(w.at[row])
        return (int(c.version[i]), int(c.record[i]), int(c.index[i]), self.messages[int(c.message[i])].name)

    def _objects(self, w: Window, params_rows: np.ndarray, reports: dict[int, tuple[Any, ...]]) -> None:
        """The object and parameter trackers (`params_rows`: the native frames the latter is given; `reports`:
        those of them that are PARAM_VALUEs, by row, given without a Frame)."""
        objects, params = self.a.objects, self.a.params
        inner = params.objects
        for row in self._in_order(w, self.objects_msgs[w.c.message]):
            objects.ctx.tick = self.seen + row
            objects.feed(w.frame(row))
            Analyses.took(objects)
        report = params.param_value
        for row in self._in_order(w, params_rows):
            args = reports.get(row)
            if args is None:
                inner.ctx.tick = self.seen + row
                params.feed(w.frame(row))
            else:  # all `feed` does with it but count it on its FTP tracker's clock, which is set again before
                report(*args)  # that tracker is given a frame and at the window's end
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
