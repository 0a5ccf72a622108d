"""Display filters over the index's columns: the TUI's filter, vectorised with numpy where it can be.

A display filter (mavscope.filter) is a tree of tests joined by and, or and not. Here each test becomes
one of:
- a **grouped** test, for a field whose value is a function of a few index columns (`mavlink.sysid` of
  the sysid column, `mavlink.msgname` and a bare message name of msgid, `signature.status` of the
  incompat flags and the interned security verdict, `ip.src` of the interned source endpoint, ...):
  the rows are grouped by those columns' values, the test's own compiled predicate (the exact Python
  closure `compile_filter` makes) is run once per distinct value on one frame that has it, and the
  answers are spread over the rows through a lookup table. Exact by construction, and a handful of
  frames rebuilt for ten million rows.
- a **numeric** test of `frame.time` or `frame.number` against numbers (comparisons, `in` with ranges):
  numpy comparisons over the column (exact: times are float64, literals within 2**53).
- a **per-frame** test for the rest (payload fields, signature values, notes, `mavlink.len`, a regular
  expression over a text ...): the exact predicate on each frame rebuilt from the index, decoded when it
  names a payload field, but only on the rows where it can hold: a payload field's messages (a
  comparison on a field a frame does not have is false, `!=` included), signed frames for the
  signature's values, rows with notes for `note.*`.
And, or and not combine boolean masks; a per-frame test only runs on the rows the others left open
(`a && b` runs b where a holds). The result equals the compiled filter's on every frame
(tests/browse/test_fastfilter.py checks it against `DisplayFilter.matches` over every row).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mavscope.browse.index import FrameIndex
from mavscope.fields.registry import FLOAT, INT, Field, FieldRegistry, PayloadField
from mavscope.filter import DisplayFilter, FilterError
from mavscope.filter.compiler import Compiler, Pred
from mavscope.filter.parser import BoolOp, Node, Not, Range, Test, Value, parse
from mavscope.mavlink.dialect import FieldDef, MessageDef
from mavscope.mavlink.frame import decode_payload

BLOCK = 1 << 20  # rows per block
FIRST_BLOCK = 1 << 14  # the first block: the first matches go out at once
DENSE = 1 << 20  # a lookup table (one byte each) over this many key values at most; more: per distinct value

# the index columns each registered field's value is a function of (with the dialect)
KEYS: dict[str, tuple[str, ...]] = {
    "frame.index": ("index",), "frame.transport": ("transport",), "frame.src": ("src",), "frame.dst": ("dst",),
    "frame.len": ("rawlen",), "mavlink.seq": ("seq",), "mavlink.sysid": ("sysid",),
    "mavlink.compid": ("compid",), "mavlink.msgid": ("msgid",), "mavlink.msgname": ("msgid",),
    "mavlink.crc_status": ("crc",), "mavlink.signed": ("iflags",), "signature.status": ("iflags", "security"),
    "signature.key": ("security",), "encryption": ("iflags",), "encryption.method": ("iflags", "security"),
    "encryption.scheme": ("iflags", "security"), "encryption.status": ("iflags", "security"),
    "encryption.reason": ("iflags", "security"), "ip.src": ("src",), "ip.dst": ("dst",), "ip.addr": ("src", "dst"),
    "udp.srcport": ("transport", "src"), "udp.dstport": ("transport", "dst"), "udp.port": ("transport", "src", "dst"),
    "tcp.srcport": ("transport", "src"), "tcp.dstport": ("transport", "dst"), "tcp.port": ("transport", "src", "dst"),
}
NUMERIC = {"frame.time": "time", "frame.number": "record"}
SIGNED_ONLY = ("signature", "signature.link_id", "signature.timestamp", "signature.time", "signature.value",
               "signature.skew")  # MISSING unless the frame's signed flag is set
EXACT = 1 << 53  # integers up to this compare exactly with float64


def _exact(v: object, ftype: str, op: str | None) -> bool:
    """Whether numpy compares a `ftype` payload value with literal `v` exactly as Python does."""
    if type(v) not in (int, float):
        return False
    if op == "&":
        return type(v) is int and 0 <= v < 1 << 63 and ftype not in ("float", "double")
    if type(v) is float:
        return v == v and ftype not in ("int64_t", "uint64_t")  # an int64 widened to float64 would round
    if ftype == "uint64_t":
        return 0 <= v <= EXACT  # type: ignore[operator]
    return abs(v) <= EXACT  # type: ignore[arg-type]


class Cancelled(Exception):
    """The scan was cancelled (raised out of a long per-frame test)."""


@dataclass
class _Grouped:
    keys: tuple[str, ...]
    pred: Pred
    radix: tuple[int, ...] = ()
    lut: np.ndarray | None = None  # dense: code -> -1 unknown, 0, 1
    seen: dict[tuple[int, ...], bool] = field(default_factory=dict)  # sparse: key values -> answer


@dataclass
class _Numeric:
    column: str
    op: str | None
    consts: list[object]


@dataclass
class _Frames:
    pred: Pred
    payload: bool
    where: str | None = None  # None: every row; "msgid", "signed", "notes"
    msgids: np.ndarray | None = None


@dataclass
class _Payload:
    """A comparison of a scalar number in the payload: decoded with numpy from the file's bytes."""

    pred: Pred  # the exact predicate, for the rows the vectorised decode does not serve
    op: str | None
    msgids: np.ndarray  # the messages that have the field (every other row: false)
    fields: dict[int, tuple[FieldDef, list[object]]]  # msgid -> the field and its literals (converted for it)


@dataclass
class _Bool:
    op: str  # "and", "or", "not"
    args: list[Plan]


Plan = _Grouped | _Numeric | _Frames | _Payload | _Bool
_DTYPES = {"record": "u4", "index": "u2", "time": "f8", "transport": "u1", "src": "u4", "dst": "u4", "rawlen": "u2",
           "crc": "u1", "iflags": "u1", "sysid": "u1", "compid": "u1", "seq": "u1", "msgid": "u4", "security": "u4",
           "offset": "i8"}
_NUMPY = {"float": "<f4", "double": "<f8", "int8_t": "<i1", "uint8_t": "<u1", "uint8_t_mavlink_version": "<u1",
          "int16_t": "<i2", "uint16_t": "<u2", "int32_t": "<i4", "uint32_t": "<u4", "int64_t": "<i8", "uint64_t": "<u8"}
SPAN = 1 << 24  # file bytes read at once for the payloads of a block
_TRUNCATED = 3  # index.CRC_CODES
_OPS: dict[str, Any] = {
    "==": np.equal, "!=": np.not_equal, "<": np.less, "<=": np.less_equal, ">": np.greater,
    ">=": np.greater_equal}


class ColumnFilter:
    """`flt` over `index`'s columns: `matches(start, end)` gives the matching row numbers of a range."""

    def __init__(self, flt: DisplayFilter, index: FrameIndex, cancelled: Callable[[], bool] = lambda: False) -> None:
        self.flt = flt
        self.index = index
        self.cancelled = cancelled
        self.registry = FieldRegistry(index.dialect)
        self.columns: set[str] = set()
        self.frames_tested = 0  # frames the per-frame tests and the groups rebuilt (for tests and benchmarks)
        self.plan = self._plan(parse(flt.text))

    # --- planning -----------------------------------------------------------------------------

    def _plan(self, node: Node) -> Plan:
        if isinstance(node, BoolOp):
            args = [self._plan(a) for a in node.args]
            args.sort(key=lambda p: isinstance(p, _Frames))  # the vectorised tests first
            return _Bool("and" if node.op == "&&" else "or", args)
        if isinstance(node, Not):
            return _Bool("not", [self._plan(node.arg)])
        return self._test(node)

    def _test(self, node: Test) -> Plan:
        comp = Compiler(self.flt.text, self.index.dialect, self.registry)
        pred = comp.compile(node)  # the exact predicate of this test alone
        lhs = self.registry.lookup(node.name.text)
        if isinstance(lhs, MessageDef):
            return self._grouped(("msgid",), pred)
        if isinstance(lhs, PayloadField):  # false wherever the frame's message has no such field
            self.columns.add("msgid")
            msgids = np.array(sorted(lhs.defs), np.uint32)
            vector = self._payload(lhs, node, comp, pred, msgids)
            return vector if vector is not None else _Frames(pred, comp.needs_payload, "msgid", msgids)
        assert isinstance(lhs, Field)
        hits = [self.registry.lookup(n) for n in comp.names]
        if not comp.needs_payload and all(isinstance(h, Field) and h.name in KEYS for h in hits):
            keys = tuple(dict.fromkeys(k for h in hits for k in KEYS[h.name]))  # type: ignore[union-attr]
            return self._grouped(keys, pred)
        if lhs.name in NUMERIC and len(hits) == 1:
            numeric = self._numeric(lhs, node, comp)
            if numeric is not None:
                return numeric
        if lhs.name in SIGNED_ONLY:
            self.columns.add("iflags")
            return _Frames(pred, comp.needs_payload, "signed")
        if lhs.name.startswith("note."):
            return _Frames(pred, comp.needs_payload, "notes")
        return _Frames(pred, comp.needs_payload)

    def _grouped(self, keys: tuple[str, ...], pred: Pred) -> _Grouped:
        self.columns.update(keys)
        return _Grouped(keys, pred)

    def _numeric(self, ff: Field, node: Test, comp: Compiler) -> _Numeric | None:
        op = node.op
        if op is not None and op not in _OPS and op != "in":
            return None
        consts: list[object] = []
        for e in node.values:
            if isinstance(e, Range):
                c: object = ("range", comp.literal_for_frame_field(ff, e.lo, op or "=="),
                             comp.literal_for_frame_field(ff, e.hi, op or "=="))
                numbers = list(c[1:])  # type: ignore[index]
            elif isinstance(e, Value):
                c = comp.literal_for_frame_field(ff, e, op or "==")
                numbers = [c]
            else:
                return None
            if not all(type(v) in (int, float) and (v == v and abs(v) <= EXACT) for v in numbers):
                return None
            consts.append(c)
        self.columns.add(NUMERIC[ff.name])
        return _Numeric(NUMERIC[ff.name], op, consts)

    def _payload(self, lhs: PayloadField, node: Test, comp: Compiler, pred: Pred,
                 msgids: np.ndarray) -> _Payload | None:
        """A payload test numpy can decide exactly: scalar numbers against numbers, or None (a display-unit
        companion, fields.units, is decided frame by frame)."""
        if lhs.divisors is not None:
            return None
        op = node.op
        if op is not None and op not in _OPS and op not in ("in", "&"):
            return None
        if any(not isinstance(e, (Value, Range)) for e in node.values) or any(
                isinstance(e, Value) and e.kind == "word" and comp._is_field_word(comp.side(node.name), e)  # type: ignore[arg-type]
                for e in node.values):
            return None
        fields: dict[int, tuple[FieldDef, list[object]]] = {}
        for mid, fd in lhs.defs.items():
            if fd.type == "char" or fd.array_length or fd.type not in _NUMPY:
                return None
            kind = FLOAT if fd.type in ("float", "double") else INT

            def convert(v: Value, fd: FieldDef = fd, kind: str = kind) -> object:
                return comp.literal_for_payload(kind, fd, v, op or "==")
            try:
                consts = [comp.elem(convert, e) for e in node.values]
            except FilterError:
                continue  # the compiled filter has no matcher for this message: false there
            for c in consts:
                for v in (c[1:] if isinstance(c, tuple) else (c,)):
                    if not _exact(v, fd.type, op):
                        return None
            fields[mid] = (fd, consts)
        self.columns.update(("crc", "iflags", "offset"))
        return _Payload(pred, op, msgids, fields)

    # --- evaluation ---------------------------------------------------------------------------

    def _block(self, start: int, end: int) -> tuple[int, int, dict[str, np.ndarray]]:
        """Copies of the columns the plan reads for rows start..end-1 (those still held): (first row, rows,
        columns). The arrays are sliced (copied) under the index's lock: no buffer of a growing array
        stays exported."""
        idx = self.index
        with idx.lock:
            first, count = idx.first, len(idx)
            i0, i1 = max(start - first, 0), min(end - first, count)
            if i1 <= i0:
                return max(start, first), 0, {}
            cols = {name: np.frombuffer(getattr(idx, "_" + name)[i0:i1], _DTYPES[name]) for name in self.columns}
            return first + i0, i1 - i0, cols

    def matches(self, start: int, end: int) -> np.ndarray:
        """The numbers of the rows start..end-1 the filter matches (uint32, ascending)."""
        first, n, cols = self._block(start, end)
        if n == 0:
            return np.empty(0, np.uint32)
        care = np.ones(n, np.bool_)
        hit = self._eval(self.plan, first, cols, care)
        return (np.flatnonzero(hit & care) + first).astype(np.uint32)

    def _eval(self, p: Plan, first: int, cols: dict[str, np.ndarray], care: np.ndarray) -> np.ndarray:
        """Where `p` holds: exact on the rows of `care`, anything elsewhere."""
        if isinstance(p, _Bool):
            if p.op == "not":
                return ~self._eval(p.args[0], first, cols, care)
            if p.op == "and":
                out = care.copy()
                for a in p.args:
                    if not out.any():
                        break
                    out &= self._eval(a, first, cols, out)
                return out
            out = np.zeros_like(care)
            for a in p.args:
                rest = care & ~out
                if not rest.any():
                    break
                out |= self._eval(a, first, cols, rest) & rest
            return out
        if isinstance(p, _Grouped):
            return self._eval_grouped(p, first, cols, care)
        if isinstance(p, _Numeric):
            return self._eval_numeric(p, cols)
        if isinstance(p, _Payload):
            return self._eval_payload(p, first, cols, care)
        return self._eval_frames(p, first, cols, care)

    def _test_frame(self, pred: Pred, payload: bool, n: int) -> bool | None:
        """The predicate on row `n`'s frame (None: the row was dropped meanwhile)."""
        try:
            f = self.index.frame(n)
        except IndexError:
            return None
        self.frames_tested += 1
        return bool(pred(f, decode_payload(f) if payload else None))

    def _eval_grouped(self, p: _Grouped, first: int, cols: dict[str, np.ndarray], care: np.ndarray) -> np.ndarray:
        rows = np.flatnonzero(care)
        out = np.zeros(len(care), np.bool_)
        if not len(rows):
            return out
        idx = self.index
        values = [cols[k][rows].astype(np.int64) for k in p.keys]
        tables = {"src": len(idx._endpoints), "dst": len(idx._endpoints), "security": len(idx._securities),
                  "transport": len(idx._transports)}
        radix = []
        for j, k in enumerate(p.keys):  # each key's range: grows (to a power of two) as larger values come
            need = tables.get(k, 256 if _DTYPES[k] == "u1" else int(values[j].max()) + 1)
            have = p.radix[j] if p.radix else 1
            radix.append(have if need <= have else 1 << max(need - 1, 1).bit_length())
        size = int(np.prod(np.array(radix, np.float64)))
        if size <= DENSE:
            radix_t = tuple(radix)
            code = values[0]
            for v, r in zip(values[1:], radix[1:]):
                code = code * r + v
            if p.lut is None or p.radix != radix_t:
                p.radix, p.lut = radix_t, np.full(size, -1, np.int8)
            lut = p.lut
            got = lut[code]
            unknown = np.flatnonzero(got < 0)
            if len(unknown):
                u, at = np.unique(code[unknown], return_index=True)
                for c, i in zip(u.tolist(), unknown[at].tolist()):
                    answer = self._test_frame(p.pred, False, first + int(rows[i]))
                    if answer is not None:
                        lut[c] = answer
                got = lut[code]
                for i in np.flatnonzero(got < 0).tolist():  # rows dropped meanwhile, and their like
                    answer = self._test_frame(p.pred, False, first + int(rows[i]))
                    got[i] = 1 if answer else 0
            out[rows] = got == 1
            return out
        stacked = np.stack(values, axis=1)
        u, at, inverse = np.unique(stacked, axis=0, return_index=True, return_inverse=True)
        answers = np.zeros(len(u), np.bool_)
        for j, (key, i) in enumerate(zip(map(tuple, u.tolist()), at.tolist())):
            got_answer = p.seen.get(key)
            if got_answer is None:
                got_answer = bool(self._test_frame(p.pred, False, first + int(rows[i])))
                if len(p.seen) < 65536:
                    p.seen[key] = got_answer
            answers[j] = got_answer
        out[rows] = answers[inverse.reshape(-1)]
        return out

    @staticmethod
    def _eval_numeric(p: _Numeric, cols: dict[str, np.ndarray]) -> np.ndarray:
        col = cols[p.column]
        if p.column == "time":
            present = ~np.isnan(col)
        else:
            col = col.astype(np.int64)
            present = np.ones(len(col), np.bool_)
        if p.op is None:
            return present
        if p.op != "in":
            return present & _OPS[p.op](col, p.consts[0])
        hit = np.zeros(len(col), np.bool_)
        for c in p.consts:
            if isinstance(c, tuple):
                hit |= (col >= c[1]) & (col <= c[2])
            else:
                hit |= col == c
        return present & hit

    def _held(self, table: dict[int, object], first: int, n: int) -> np.ndarray:
        """Mask of the block's rows that have an entry in the side table `table` (notes, raw bytes)."""
        with self.index.lock:
            at = self.index.first
            held = np.fromiter(table.keys(), np.int64, len(table))
        held = held + at - first
        mask = np.zeros(n, np.bool_)
        mask[held[(held >= 0) & (held < n)]] = True
        return mask

    def _eval_payload(self, p: _Payload, first: int, cols: dict[str, np.ndarray], care: np.ndarray) -> np.ndarray:
        out = np.zeros(len(care), np.bool_)
        msgid = cols["msgid"]
        sel = care & np.isin(msgid, p.msgids)
        if not sel.any():
            return out
        data = self.index._bytes
        fast = sel & (cols["crc"] != _TRUNCATED) & ((cols["iflags"] & 0xFE) == 0) & ~self._held(
            self.index._raw, first, len(care))  # type: ignore[arg-type]
        if data is None:
            fast[:] = False
        slow = np.flatnonzero(sel & ~fast)
        for k, i in enumerate(slow.tolist()):
            if not k & 0xFFF and self.cancelled():
                raise Cancelled
            out[i] = bool(self._test_frame(p.pred, True, first + i))
        rows = np.flatnonzero(fast)
        offsets = cols["offset"][rows]
        spans = offsets // SPAN
        for span in np.unique(spans).tolist():
            at = rows[spans == span]
            off = cols["offset"][at]
            lo = int(off.min())
            buf = np.frombuffer(data.get(lo, int(off.max()) + 300 - lo), np.uint8)  # type: ignore[union-attr]
            buf = np.concatenate([buf, np.zeros(300, np.uint8)])  # a frame cut by the file's end reads zeros
            rel = off - lo
            hdr = np.where(buf[rel] == 0xFD, 10, 6)
            plen = buf[rel + 1].astype(np.int64)
            ids = msgid[at]
            for mid in np.unique(ids).tolist():
                which = np.flatnonzero(ids == mid)
                out[at[which]] = self._payload_values(p, mid, buf, rel[which] + hdr[which], plen[which])
        return out

    @staticmethod
    def _payload_values(p: _Payload, mid: int, buf: np.ndarray, start: np.ndarray, plen: np.ndarray) -> np.ndarray:
        """The test on message `mid`'s frames whose payloads start at `start` in `buf` (`plen` bytes long)."""
        got = p.fields.get(mid)
        if got is None:
            return np.zeros(len(start), np.bool_)  # the literals are no values of this message's field
        fd, consts = got
        size = np.dtype(_NUMPY[fd.type]).itemsize
        cols = fd.offset + np.arange(size)
        take = buf[start[:, None] + cols[None, :]]
        take[cols[None, :] >= plen[:, None]] = 0  # bytes past the payload's length (trimmed zeros)
        values = np.ascontiguousarray(take).view(_NUMPY[fd.type]).reshape(-1)
        if fd.type in ("float", "double"):
            values = values.astype(np.float64)
        elif fd.type not in ("uint64_t", "int64_t"):
            values = values.astype(np.int64)
        if p.op is None:
            return np.ones(len(start), np.bool_)
        if p.op == "&":
            return np.asarray((values & consts[0]) != 0)
        if p.op != "in":
            return _OPS[p.op](values, consts[0])
        hit = np.zeros(len(start), np.bool_)
        for c in consts:
            if isinstance(c, tuple):
                hit |= (values >= c[1]) & (values <= c[2])
            else:
                hit |= values == c
        return hit

    def _eval_frames(self, p: _Frames, first: int, cols: dict[str, np.ndarray], care: np.ndarray) -> np.ndarray:
        out = np.zeros(len(care), np.bool_)
        sel = care
        if p.where == "msgid":
            assert p.msgids is not None
            sel = care & np.isin(cols["msgid"], p.msgids)
        elif p.where == "signed":
            sel = care & ((cols["iflags"] & 1) != 0)
        elif p.where == "notes":
            sel = care & self._held(self.index._notes, first, len(care))  # type: ignore[arg-type]
        test, pred, payload = self._test_frame, p.pred, p.payload
        for k, i in enumerate(np.flatnonzero(sel).tolist()):
            if not k & 0xFFF and self.cancelled():
                raise Cancelled
            out[i] = bool(test(pred, payload, first + i))
        return out

    def scan(self, start: int, end: int) -> Iterator[tuple[int, np.ndarray]]:
        """Rows start..end-1 in blocks: (end of the block, its matching rows); Cancelled when asked."""
        at = start
        size = FIRST_BLOCK
        while at < end:
            stop = min(at + size, end)
            yield stop, self.matches(at, stop)
            if self.cancelled():
                raise Cancelled
            at = stop
            size = BLOCK
