"""Frames as column batches: the one form the frame-wide analyses read (statistics, sequence, expert).

A `FrameBatch` is a run of frames in capture order as numpy columns (record, time, transport, endpoints,
header numbers, message, size, CRC and signature verdicts, and whether the frame is *clean*: good CRC, no
note, plaintext, no verdict but `no-key`), and the `Frame` of any row on demand. Two makers, one form:

- `FrameBatch.of_frames(frames, tables)`: frames the Python pipeline made (the pure engine, the TUI, and
  the records the native walker hands back);
- `FrameBatch.of_window(chunk, py, pos, ends, messages, tables)`: a chunk of the native walker's column
  mode (clean frames, no `Frame` made until a row is asked for) merged with the handed-back frames `py`,
  the j-th of them after `pos[j]` native rows.

Analyses count what every frame feeds with numpy over the columns and build a `Frame` only for the rows
they read one by one (commands, HEARTBEATs, the exceptions of the sequence counters): see
`StatsBuilder.add_batch`, `SeqChannels.feed_batch` and `Expert.add_batch`. `Tables` gives the text
columns their ids (endpoints, message labels) for a whole pass, so ids mean the same in every batch.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from operator import itemgetter
from typing import Any, Protocol

import numpy as np

from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import FieldDef, MessageDef, wire_format
from mavscope.mavlink.frame import CrcStatus, Frame, Signature, SignatureStatus, decode_payload, new_frame
from mavscope.mavlink.semantics import message_label
from mavscope.native.core import COLUMN_TRANSPORTS, NOTE_BAD_CRC, NOTE_UNSIGNED, NOTE_V1

TRANSPORTS: tuple[str, ...] = ("udp", "tcp", "tlog", "raw")  # FrameBatch.transport codes
CRC_STATUSES: tuple[CrcStatus, ...] = tuple(CrcStatus)  # FrameBatch.crc codes
VERDICTS: tuple[str, ...] = ("unsigned", *(s.value for s in SignatureStatus))  # FrameBatch.verdict codes
UNSIGNED, NO_KEY = 0, VERDICTS.index(SignatureStatus.NO_KEY.value)
CRC_OK, CRC_BAD = CRC_STATUSES.index(CrcStatus.OK), CRC_STATUSES.index(CrcStatus.BAD)
# the notes a native chunk gives as codes (FrameBatch.coded) -> their bits
NOTE_CODES: dict[str, int] = {"bad-crc": NOTE_BAD_CRC, "unsigned-in-signed-stream": NOTE_UNSIGNED,
                              "v1-in-signed-stream": NOTE_V1}
_CRC_CODE = {s: k for k, s in enumerate(CRC_STATUSES)}
_VERDICT_CODE = {s: k for k, s in enumerate(VERDICTS)}
_TRANSPORT_CODE = {t: k for k, t in enumerate(TRANSPORTS)}
# the native transport column's codes -> FrameBatch's (0 where the walker writes none)
_NATIVE_TRANSPORT = np.array([0 if t is None else _TRANSPORT_CODE[t] for t in COLUMN_TRANSPORTS] or [0], np.uint8)


class Tables:
    """Ids for a pass's text columns: endpoints (-1: none) and message labels (`message_label`)."""

    def __init__(self) -> None:
        self.endpoints: list[Endpoint] = []
        self.texts: list[str] = []
        self._ids: dict[Endpoint, int] = {}
        self.labels: list[str] = []
        self.label_defs: list[MessageDef | None] = []
        self._labels: dict[str, int] = {}
        self._native: list[int] = []  # the native walker's endpoint ids -> ours
        # id(messages) -> (messages, per table position the label id of its message)
        self._positions: dict[int, tuple[Sequence[MessageDef], np.ndarray]] = {}

    def endpoint(self, e: Endpoint | None) -> int:
        if e is None:
            return -1
        k = self._ids.get(e)
        if k is None:
            k = self._ids[e] = len(self.endpoints)
            self.endpoints.append(e)
            self.texts.append(e.text)
        return k

    def text(self, k: int) -> str:
        """The endpoint's "ip:port" ("" for none)."""
        return self.texts[k] if k >= 0 else ""

    def label(self, msgid: int, md: MessageDef | None) -> int:
        name = message_label(msgid, md)
        k = self._labels.get(name)
        if k is None:
            k = self._labels[name] = len(self.labels)
            self.labels.append(name)
            self.label_defs.append(md)
        return k

    def native_endpoints(self, ends: Sequence[Endpoint], reset: bool = False) -> np.ndarray:
        """Our id of each of the walker's endpoints `ends` (its ids index `ends`), plus -1 for its -1."""
        if reset:
            self._native = []
        for e in ends[len(self._native):]:
            self._native.append(self.endpoint(e))
        return np.asarray([*self._native, -1], np.int32)

    def native_labels(self, messages: Sequence[MessageDef]) -> np.ndarray:
        """Per position of the walker's layout table, the label id of its message."""
        got = self._positions.get(id(messages))
        if got is None or got[0] is not messages:  # (the list kept with its ids: an id is never reused for it)
            got = self._positions[id(messages)] = (
                messages, np.asarray([self.label(md.id, md) for md in messages], np.int32))
        return got[1]


class NativeChunk(Protocol):
    """What a native column chunk holds (mavscope.native.chunk.Chunk)."""

    n: int
    record: np.ndarray
    index: np.ndarray
    time: np.ndarray
    time_ok: np.ndarray
    transport: np.ndarray
    src: np.ndarray
    dst: np.ndarray
    offset: np.ndarray
    version: np.ndarray
    len: np.ndarray
    iflags: np.ndarray
    cflags: np.ndarray
    seq: np.ndarray
    sysid: np.ndarray
    compid: np.ndarray
    msgid: np.ndarray
    message: np.ndarray
    crc: np.ndarray
    sig_link: np.ndarray
    sig_time: np.ndarray
    signed: np.ndarray
    note: np.ndarray
    raw: bytes
    raw_at: np.ndarray
    payload: memoryview
    payload_at: np.ndarray


Noted = Callable[[Frame, int], Frame]  # a clean row's Frame -> the Frame its note code (Chunk.note) says


def clean(f: Frame) -> bool:
    """A frame the native walker takes as it is: good CRC, no note, plaintext, no verdict but `no-key`."""
    if f.crc_status is not CrcStatus.OK or f.notes or f.incompat_flags & ~1:
        return False
    sec = f.security
    if sec is None:
        return True
    return (sec.signature_status in (None, SignatureStatus.NO_KEY)
            and sec.encryption is None)


def _verdict(f: Frame) -> int:
    status = f.signature_status
    return UNSIGNED if status is None else _VERDICT_CODE[status.value]


class FrameBatch:
    """Frames in capture order as columns (see the module docstring); `frame(row)` gives a row's Frame."""

    __slots__ = ("n", "record", "time", "timed", "transport", "src", "dst", "version", "seq", "sysid", "compid",
                 "msgid", "label", "size", "crc", "verdict", "signed", "clean", "coded", "tables", "_frames", "_make",
                 "_raw", "_many", "_payloads", "_block")
    n: int
    record: np.ndarray  # int64: the capture record that completed the frame
    time: np.ndarray  # float64: its time (0.0 where `timed` is not set)
    timed: np.ndarray  # bool: the record has a time
    transport: np.ndarray  # uint8: TRANSPORTS
    src: np.ndarray  # int32: Tables.endpoints (-1: none)
    dst: np.ndarray
    version: np.ndarray  # uint8
    seq: np.ndarray
    sysid: np.ndarray
    compid: np.ndarray
    msgid: np.ndarray  # uint32
    label: np.ndarray  # int32: Tables.labels
    size: np.ndarray  # int32: bytes on the wire
    crc: np.ndarray  # uint8: CRC_STATUSES
    verdict: np.ndarray  # uint8: VERDICTS
    signed: np.ndarray  # bool: a signature block
    clean: np.ndarray  # bool: see `clean`
    coded: np.ndarray  # uint8: NOTE_CODES bits of a row whose only notes a native chunk gave as codes, else 0
    tables: Tables

    def __init__(self, n: int, tables: Tables, columns: dict[str, np.ndarray], frames: list[Frame | None],
                 make: Callable[[int], Frame] | None = None, raw: Callable[[int], bytes] | None = None,
                 many: Callable[[list[int]], list[Frame]] | None = None,
                 payloads: Callable[[list[int]], list[tuple[MessageDef | None, bytes]]] | None = None) -> None:
        self.n, self.tables, self._frames, self._make = n, tables, frames, make
        self._raw, self._many, self._payloads = raw, many, payloads
        # a native chunk's payload bytes and where each row's begins, and per row its chunk row (-1: a Frame
        # of the Python pipeline; None: every row is the chunk's own)
        self._block: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None
        for name, values in columns.items():
            setattr(self, name, values)

    @property
    def sender(self) -> np.ndarray:
        """sysid << 8 | compid per row (int64)."""
        return self.sysid.astype(np.int64) << 8 | self.compid

    def frame(self, row: int) -> Frame:
        f = self._frames[row]
        if f is None:
            assert self._make is not None
            f = self._frames[row] = self._make(row)
        return f

    def frames(self, rows: Sequence[int]) -> list[Frame]:
        """The Frames of `rows`, those not made yet made together."""
        got = self._frames
        missing = [r for r in rows if got[r] is None]
        if missing:
            assert self._many is not None
            for r, f in zip(missing, self._many(missing)):
                got[r] = f
        return [got[r] for r in rows]  # type: ignore[misc]

    def raw(self, row: int) -> bytes:
        """The row's frame as on the wire (without making its Frame)."""
        f = self._frames[row]
        if f is not None or self._raw is None:
            return self.frame(row).raw
        return self._raw(row)

    def decoded(self, rows: Sequence[int], names: frozenset[str], *, bad_crc: bool = False,
                ) -> list[dict[str, object] | None]:
        """Per row of `rows`, what `Expert.fields` gives its Frame: the decoded payload where its message is
        one of `names` and its CRC is not bad (with `bad_crc`, bad too: `decode_payload`'s), else None. The
        rows without a Frame yet (a native chunk's: plaintext, their payload as on the wire) are decoded per
        message in one call (MessageDef.decode_many) and get no Frame; the others are their Frames'
        `decode_payload`."""
        out: list[dict[str, object] | None] = [None] * len(rows)
        got = self._frames
        bad = np.zeros(len(rows), np.bool_) if bad_crc or not len(rows) else \
            self.crc[np.asarray(rows, np.int64)] == CRC_BAD
        bare = [k for k, r in enumerate(rows) if got[r] is None and not bad[k]]
        if bare:
            assert self._payloads is not None
            groups: dict[int, tuple[MessageDef, list[int], list[bytes]]] = {}
            for k, (md, payload) in zip(bare, self._payloads([rows[k] for k in bare])):
                if md is not None and md.name in names:
                    g = groups.get(id(md))
                    if g is None:
                        g = groups[id(md)] = (md, [], [])
                    g[1].append(k)
                    g[2].append(payload)
            for md, ks, payloads in groups.values():
                for k, fields in zip(ks, md.decode_many(payloads)):
                    out[k] = fields
        for k, r in enumerate(rows):
            f = got[r]
            if f is not None and not bad[k] and f.msgdef is not None and f.msgdef.name in names:
                out[k] = decode_payload(f)
        return out

    def field_column(self, rows: Sequence[int], fd: FieldDef) -> tuple[np.ndarray, np.ndarray]:
        """Per row of `rows` (frames of scalar field `fd`'s message), the field's value as `decode_payload`
        gives it, in a numpy array of the field's type, and whether the row has one (not where the payload
        cannot be decoded): a native chunk's rows read from its payload bytes by numpy, zero-extended as
        `decode` pads a short payload; the others from their Frames."""
        values = np.zeros(len(rows), np.dtype(wire_format((fd,))))
        present = np.zeros(len(rows), np.bool_)
        idx = np.asarray(rows, np.int64)
        framed = range(len(rows))
        if self._block is not None and len(rows):
            pay, at, native_of = self._block
            chunk_row = idx if native_of is None else native_of[idx]
            ks = np.flatnonzero(chunk_row >= 0)
            src = chunk_row[ks]
            start, length = at[src] + fd.offset, at[src + 1] - at[src]
            raw = np.zeros((len(src), fd.size), np.uint8)
            for j in range(fd.size):
                there = fd.offset + j < length
                raw[there, j] = pay[start[there] + j]
            values[ks] = raw.reshape(-1).view(values.dtype)
            present[ks] = True
            framed = np.flatnonzero(chunk_row < 0).tolist()  # type: ignore[assignment]
        for k in framed:
            fields = decode_payload(self.frame(rows[k]))
            if fields is not None and fd.name in fields:
                values[k] = fields[fd.name]
                present[k] = True
        return values, present

    def of_messages(self, names: Iterable[str | int]) -> np.ndarray:
        """Per row, whether its message is one of `names` (message names, or ids as ints)."""
        ids = self.tables._labels
        want = [ids[n] for n in names if isinstance(n, str) and n in ids]
        nums = [n for n in names if isinstance(n, int)]
        mask = np.isin(self.label, np.asarray(want, np.int32)) if want else np.zeros(self.n, np.bool_)
        if nums:
            mask |= np.isin(self.msgid, np.asarray(nums, np.uint32))
        return mask

    def msgname(self, row: int) -> str:
        """The message's name as the sequence findings name it (its id for an unknown one)."""
        md = self.tables.label_defs[int(self.label[row])]
        return md.name if md is not None else str(int(self.msgid[row]))

    @classmethod
    def of_frames(cls, frames: Sequence[Frame], tables: Tables) -> FrameBatch:
        """The batch of frames the Python pipeline made."""
        n = len(frames)
        if not n:
            return cls(0, tables, _empty(), [])
        (record, _, time, transport, src, dst, _, raw, version, _, _, _, seq, sysid, compid, msgid, _, crc_status,
         msgdef, signature, *_rest) = zip(*frames)
        timed = np.fromiter((t is not None for t in time), np.bool_, n)
        ep, lab = tables.endpoint, tables.label
        columns = {
            "record": np.asarray(record, np.int64),
            "time": np.asarray([0.0 if t is None else t for t in time], np.float64),
            "timed": timed,
            "transport": np.asarray([_TRANSPORT_CODE[t] for t in transport], np.uint8),
            "src": np.asarray([ep(e) for e in src], np.int32),
            "dst": np.asarray([ep(e) for e in dst], np.int32),
            "version": np.asarray(version, np.uint8),
            "seq": np.asarray(seq, np.uint8),
            "sysid": np.asarray(sysid, np.uint8),
            "compid": np.asarray(compid, np.uint8),
            "msgid": np.asarray(msgid, np.uint32),
            "label": np.asarray([lab(i, md) for i, md in zip(msgid, msgdef)], np.int32),
            "size": np.asarray([len(r) for r in raw], np.int32),
            "crc": np.asarray([_CRC_CODE[s] for s in crc_status], np.uint8),
            "verdict": np.asarray([_verdict(f) for f in frames], np.uint8),
            "signed": np.asarray([s is not None for s in signature], np.bool_),
            "clean": np.asarray([clean(f) for f in frames], np.bool_),
            "coded": np.zeros(n, np.uint8),
        }
        return cls(n, tables, columns, list(frames), many=_no_frames)

    @classmethod
    def of_window(cls, c: NativeChunk, py: Sequence[Frame], pos: Sequence[int], ends: Sequence[Endpoint],
                  messages: Sequence[MessageDef], tables: Tables, reset: bool = False,
                  noted: Noted | None = None) -> FrameBatch:
        """Chunk `c`'s rows (clean frames, and frames whose notes the chunk gives as codes: `noted` makes
        their Frames) and the handed-back frames `py` (the j-th after `pos[j]` native rows), in capture
        order."""
        n, p = c.n, len(py)
        if not p:
            return cls._native(c, ends, messages, tables, reset, noted)
        size = n + p
        at = np.asarray(pos, np.int64)
        gn = np.arange(n) + np.searchsorted(at, np.arange(n), side="right")
        gp = at + np.arange(p)
        a = cls._native(c, ends, messages, tables, reset, noted)
        b = cls.of_frames(py, tables)
        columns = {}
        for name in _COLUMNS:
            x, y = getattr(a, name), getattr(b, name)
            out = np.empty(size, x.dtype)
            out[gn] = x
            out[gp] = y
            columns[name] = out
        frames: list[Frame | None] = [None] * size
        for j, f in zip(gp.tolist(), py):
            frames[j] = f
        native_of = np.full(size, -1, np.int64)
        native_of[gn] = np.arange(n)
        make, raw, many, payloads = a._make, a._raw, a._many, a._payloads
        assert make is not None and raw is not None and many is not None and payloads is not None
        merged = cls(size, tables, columns, frames, lambda row: make(int(native_of[row])),
                     lambda row: raw(int(native_of[row])), lambda rows: many(native_of[rows].tolist()),
                     lambda rows: payloads(native_of[rows].tolist()))
        if a._block is not None:
            merged._block = (a._block[0], a._block[1], native_of)
        return merged

    @classmethod
    def _native(cls, c: NativeChunk, ends: Sequence[Endpoint], messages: Sequence[MessageDef], tables: Tables,
                reset: bool, noted: Noted | None) -> FrameBatch:
        n = c.n
        ids = tables.native_endpoints(ends, reset)
        signed = np.asarray(c.signed, np.bool_)
        clean_rows = c.note == 0
        columns = {
            "record": c.record, "time": np.where(c.time_ok, c.time, 0.0), "timed": np.asarray(c.time_ok, np.bool_),
            "transport": _NATIVE_TRANSPORT[c.transport], "src": ids[c.src], "dst": ids[c.dst],
            "version": c.version, "seq": c.seq, "sysid": c.sysid, "compid": c.compid, "msgid": c.msgid,
            "label": tables.native_labels(messages)[c.message] if n else np.empty(0, np.int32),
            "size": np.diff(c.raw_at).astype(np.int32) if n else np.empty(0, np.int32),
            "crc": np.where(c.note & NOTE_BAD_CRC, CRC_BAD, CRC_OK).astype(np.uint8),
            "verdict": np.where(signed, NO_KEY, UNSIGNED).astype(np.uint8), "signed": signed, "clean": clean_rows,
            "coded": c.note,
        }
        notes_of = c.note
        ends_of = [*tables.endpoints]
        transports = TRANSPORTS
        chunk_raw, raw_at = c.raw, c.raw_at

        def raw_of(i: int) -> bytes:
            return chunk_raw[int(raw_at[i]):int(raw_at[i + 1])]

        messages_of = list(messages) + [None]
        src_ids, dst_ids, transport_ids = columns["src"], columns["dst"], columns["transport"]
        ends_of.append(None)  # type: ignore[arg-type]  # an id of -1: no endpoint

        sources = (c.record, c.index, c.time, c.time_ok, transport_ids, src_ids, dst_ids, c.offset, c.version, c.len,
                   c.iflags, c.cflags, c.seq, c.sysid, c.compid, c.msgid, c.crc, c.message, signed, c.sig_link,
                   c.sig_time, notes_of)

        def build(a: int, z: int, record: int, index: int, time: float, ok: bool, transport: int, src: int, dst: int,
                  offset: int, version: int, length: int, iflags: int, cflags: int, seq: int, sysid: int,
                  compid: int, msgid: int, crc: int, message: int, is_signed: bool, link: int, stamp: int,
                  code: int) -> Frame:
            raw = chunk_raw[a:z]
            f = new_frame(
                record, index, time if ok else None, transports[transport], ends_of[src], ends_of[dst], offset,
                raw, version, length, iflags, cflags, seq, sysid, compid, msgid, crc, CrcStatus.OK,
                messages_of[message], Signature(link, stamp, raw[-6:]) if is_signed else None, (), None)
            if code:
                assert noted is not None, "a chunk with notes needs `noted`"
                f = noted(f, code)
            return f

        lists: list[list[Any]] = []  # every column as a list, made once where rows are asked for one by one

        def many(rows: list[int]) -> list[Frame]:
            if lists:
                at, cols = lists[0], lists[1:]
                if len(rows) == 1:
                    r = rows[0]
                    return [build(at[r], at[r + 1], *[col[r] for col in cols])]
                take, ends = itemgetter(*rows), itemgetter(*[r + 1 for r in rows])
                return [build(*values) for values in zip(take(at), ends(at), *(take(col) for col in cols))]
            idx = np.asarray(rows, np.int64)
            return [build(*values) for values in zip(raw_at[idx].tolist(), raw_at[idx + 1].tolist(),
                                                     *(col[idx].tolist() for col in sources))]

        def make(i: int) -> Frame:
            if not lists:  # (a detector judging rows one by one: one conversion per batch, not per row)
                lists.extend([raw_at.tolist(), *(col.tolist() for col in sources)])
            return many([i])[0]

        payload, payload_at, message_col = c.payload, c.payload_at, c.message

        def payloads(rows: list[int]) -> list[tuple[MessageDef | None, bytes]]:
            idx = np.asarray(rows, np.int64)
            return [(messages_of[m], bytes(payload[a:z])) for m, a, z in zip(
                message_col[idx].tolist(), payload_at[idx].tolist(), payload_at[idx + 1].tolist())]

        batch = cls(n, tables, columns, [None] * n, make, raw_of, many, payloads)
        batch._block = (np.frombuffer(payload, np.uint8) if n else np.empty(0, np.uint8), payload_at, None)
        return batch


def _no_frames(rows: list[int]) -> list[Frame]:
    raise AssertionError(f"rows {rows[:3]} of a batch of Frames have no Frame")


_COLUMNS = ("record", "time", "timed", "transport", "src", "dst", "version", "seq", "sysid", "compid", "msgid",
            "label", "size", "crc", "verdict", "signed", "clean", "coded")
_DTYPES: dict[str, Any] = {"record": np.int64, "time": np.float64, "timed": np.bool_, "transport": np.uint8,
                           "src": np.int32, "dst": np.int32, "version": np.uint8, "seq": np.uint8,
                           "sysid": np.uint8, "compid": np.uint8, "msgid": np.uint32, "label": np.int32,
                           "size": np.int32, "crc": np.uint8, "verdict": np.uint8, "signed": np.bool_,
                           "clean": np.bool_, "coded": np.uint8}


def _empty() -> dict[str, np.ndarray]:
    return {name: np.empty(0, _DTYPES[name]) for name in _COLUMNS}
