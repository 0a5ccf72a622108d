"""The display-filter compiler: an AST -> nested closures over the field registry, run once per frame.

No `eval`. Literals are converted once at compile time (enum names to numbers through the dialect,
addresses to networks, regexes compiled), and the payload is decoded per frame only when the filter
names a payload field. A comparison on a field the frame does not have is false, `!=` included
(Wireshark semantics).
"""

from __future__ import annotations

import difflib
import ipaddress
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import cast

import re2

from mavscope.fields.registry import (
    BYTES,
    FLOAT,
    INT,
    IP,
    MISSING,
    NONE,
    STR,
    Field,
    FieldRegistry,
    PayloadField,
    payload_value,
)
from mavscope.fields.units import companion_name, looks_displayed, scale_of
from mavscope.filter.errors import FilterError
from mavscope.filter.lexer import KEYWORDS
from mavscope.filter.matchers import CMP, matcher
from mavscope.filter.parser import BoolOp, Name, Node, Not, Range, Test, Value, parse
from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef
from mavscope.mavlink.frame import Frame, decode_payload

Pred = Callable[[Frame, "dict[str, object] | None"], bool]
Getter = Callable[[Frame, "dict[str, object] | None"], object]


MAX_DIGITS = 40  # a number literal longer than this is no field's value (uint64 has 20 digits)


def _number(v: Value) -> int | float:
    """The number a literal spells; ValueError for one too long or not finite (no field holds it)."""
    t = v.text
    neg = t.startswith("-")
    body = t[1:] if neg else t
    if len(body) > MAX_DIGITS:
        raise ValueError(f"a number of {len(body)} characters")
    if body[:2].lower() == "0x":
        n: int | float = int(body, 16)
    elif any(c in body for c in ".eE"):
        n = float(body)
        if not math.isfinite(n):
            raise ValueError("a number too large for a float")
    else:
        n = int(body)
    return -n if neg else n


def _regex(text: str) -> object:
    """`text` compiled by RE2: matching takes time linear in the text, whatever the pattern, so a
    sender's STATUSTEXT cannot make a filter run for minutes (no catastrophic backtracking)."""
    options = re2.Options()
    options.log_errors = False  # the error comes back as an exception, not as a line on stderr
    options.max_mem = REGEX_MEMORY
    return re2.compile(text, options)


REGEX_MEMORY = 8 << 20  # bytes RE2 may use for one pattern


def _field_kind(fd: FieldDef) -> str:
    if fd.type == "char":
        return STR
    if fd.array_length:
        return "array"
    if fd.type in ("float", "double"):
        return FLOAT
    return INT


@dataclass
class _Side:
    """A resolved field: how to get its value, and what literals must be converted to."""

    name: Name
    getter: Getter
    payload: bool
    kinds: dict[int, tuple[str, FieldDef | None]] = field(default_factory=dict)  # msgid -> kind (payload)
    frame_field: Field | None = None
    companion: bool = False  # a display-unit companion of a scaled field (fields.units)


class Compiler:
    def __init__(self, text: str, dialect: Dialect, registry: FieldRegistry | None = None) -> None:
        self.text = text
        self.dialect = dialect
        self.registry = registry or FieldRegistry(dialect)
        self.needs_payload = False
        self.names: set[str] = set()
        self.warnings: list[str] = []  # what the filter may not mean (unit_warnings): said, not refused

    def error(self, message: str, node: Name | Value | Range) -> FilterError:
        return FilterError(message, self.text, node.pos, node.end - node.pos)

    # names --------------------------------------------------------------------------------------

    def resolve(self, name: Name) -> Field | PayloadField | MessageDef:
        hit = self.registry.lookup(name.text)
        if hit is None:
            msg = f'unknown field "{name.text}"'
            close = difflib.get_close_matches(name.text, self.registry.all_names(), n=1, cutoff=0.75)
            if close:
                msg += f'; did you mean "{close[0]}"?'
            raise self.error(msg, name)
        self.names.add(name.text)
        return hit

    def side(self, name: Name) -> _Side | MessageDef:
        hit = self.resolve(name)
        if isinstance(hit, MessageDef):
            return hit
        if isinstance(hit, Field):
            get = hit.get
            return _Side(name, lambda f, _d: get(f), False, frame_field=hit)
        self.needs_payload = True
        defs = hit.defs
        kinds: dict[int, tuple[str, FieldDef | None]] = {mid: (_field_kind(fd), fd) for mid, fd in defs.items()}
        if hit.divisors is not None:  # a display-unit companion (fields.units): a float in that unit
            kinds = {mid: (FLOAT if kind == INT else kind, fd) for mid, (kind, fd) in kinds.items()}
            return _Side(name, hit.value, True, kinds, companion=True)
        return _Side(name, lambda f, d: payload_value(defs, f, d), True, kinds)

    # literals -----------------------------------------------------------------------------------

    def convert(self, kind: str, v: Value, *, enum: str = "", choices: tuple[str, ...] = (),
                msgid_field: bool = False, op: str = "==") -> object:
        """A literal as a value comparable with a field of `kind` (FilterError if it cannot be)."""
        if kind in (INT, FLOAT, "array"):
            if v.kind == "number":
                n = self.number(v)
                if op == "&" and not isinstance(n, int):
                    raise self.error(f'"&" needs an integer, not {v.text}', v)
                return n
            if kind == INT or kind == "array":
                if msgid_field:
                    md = self.dialect.by_name.get(v.text)
                    if md is not None:
                        return md.id
                if enum:
                    ed = self.dialect.enums.get(enum)
                    entry = ed.by_name.get(v.text) if ed is not None else None
                    if entry is not None:
                        return entry.value
                hit = self.dialect.enum_value(v.text)
                if hit is not None:
                    return hit[1]
                ed = self.dialect.enums.get(enum) if enum else None
                names = list(ed.by_name) if ed is not None else [n for e in self.dialect.enums.values()
                                                                  for n in e.by_name]
                close = difflib.get_close_matches(v.text, names, n=1, cutoff=0.75)
                hint = f'; did you mean "{close[0]}"?' if close else ""
                raise self.error(f'"{v.text}" is not a number, nor an enum name in the loaded dialects{hint}', v)
            raise self.error(f'"{v.text}" is not a number', v)
        if kind == STR:
            if op == "matches":
                try:
                    return _regex(v.text)
                except re2.error as exc:
                    why = exc.args[0].decode("utf-8", "replace") if exc.args and isinstance(exc.args[0], bytes) else exc
                    raise self.error(f"bad regular expression (RE2 syntax: no backreferences or lookaround): {why}",
                                     v) from None
            if choices and op in ("==", "!=", "in") and v.text not in choices:
                raise self.error(f'"{v.text}" is not one of {", ".join(choices)}', v)
            return v.text
        if kind == IP:
            try:
                return ipaddress.ip_network(v.text, strict=False)
            except ValueError:
                raise self.error(f'"{v.text}" is not an IP address or network', v) from None
        if kind == BYTES:
            if re.fullmatch(r"[0-9a-fA-F]{2}([:\- ]?[0-9a-fA-F]{2})*", v.text) and v.kind != "string":
                return bytes.fromhex(re.sub(r"[:\- ]", "", v.text))
            if v.kind == "string" and re.fullmatch(r"[0-9a-fA-F]{2}(:[0-9a-fA-F]{2})+", v.text):
                return bytes.fromhex(v.text.replace(":", ""))
            return v.text.encode("utf-8", "surrogatepass")
        raise self.error("cannot compare this field", v)

    def number(self, v: Value) -> int | float:
        try:
            return _number(v)
        except ValueError as exc:
            raise self.error(f'"{v.text[:20]}{"…" if len(v.text) > 20 else ""}" is not a usable number ({exc})',
                             v) from None

    def convert_time(self, v: Value) -> float:
        if v.kind == "number":
            n = self.number(v)
            try:
                return float(n)
            except OverflowError:
                raise self.error("a time too large", v) from None
        try:
            dt = datetime.fromisoformat(v.text.replace("Z", "+00:00"))
        except ValueError:
            raise self.error(f'"{v.text}" is neither Unix seconds nor an ISO-8601 time', v) from None
        if dt.tzinfo is None:
            dt = dt.replace(tzinfo=timezone.utc)
        return dt.timestamp()

    def literal_for_frame_field(self, ff: Field, v: Value, op: str) -> object:
        if ff.type == NONE:
            raise self.error(f'"{ff.name}" only tells whether a frame has it: use it alone, without a comparison',
                             v)
        if ff.name in ("frame.time", "signature.time"):
            if op in ("matches", "contains", "&"):
                raise self.error(f'"{op}" cannot be used on the time field "{ff.name}"', v)
            return self.convert_time(v)
        kind = ff.type
        if op == "matches" and kind != STR:
            raise self.error(f'"matches" needs a text field; "{ff.name}" is not one', v)
        if op == "contains" and kind not in (STR, BYTES):
            raise self.error(f'"contains" needs a text or bytes field; "{ff.name}" is not one', v)
        if op == "&" and kind != INT:
            raise self.error(f'"&" needs an integer field; "{ff.name}" is not one', v)
        if kind == IP and op in ("<", "<=", ">", ">="):
            raise self.error("addresses compare with ==, != and in only", v)
        if ff.values and v.kind != "number":
            return self.value_name(ff, v)
        return self.convert(kind, v, enum=ff.enum, choices=ff.choices, msgid_field=ff.name == "mavlink.msgid", op=op)

    def value_name(self, ff: Field, v: Value) -> int:
        """The number a name of `ff`'s values stands for (`ftp.opcode == OpenFileRO`)."""
        for number, name in ff.values:
            if name == v.text:
                return number
        names = list(dict.fromkeys(name for _, name in ff.values))
        close = difflib.get_close_matches(v.text, names, n=1, cutoff=0.75)
        hint = f'; did you mean "{close[0]}"?' if close else f" (one of {', '.join(names)})"
        raise self.error(f'"{v.text}" is not a number nor a name of {ff.name} values{hint}', v)

    # tests --------------------------------------------------------------------------------------

    def compile(self, node: Node) -> Pred:
        if isinstance(node, BoolOp):
            preds = [self.compile(a) for a in node.args]
            if node.op == "&&":
                return lambda f, d: all(p(f, d) for p in preds)
            return lambda f, d: any(p(f, d) for p in preds)
        if isinstance(node, Not):
            p = self.compile(node.arg)
            return lambda f, d: not p(f, d)
        return self.test(node)

    def test(self, node: Test) -> Pred:
        lhs = self.side(node.name)
        if isinstance(lhs, MessageDef):
            if node.op is not None:
                raise self.error(f'"{node.name.text}" is a message: use it alone, or compare one of its fields '
                                 f'({node.name.text}.field)', node.name)
            mid = lhs.id
            name = lhs.name
            return lambda f, d: f.msgid == mid and f.msgdef is not None and f.msgdef.name == name
        getter = lhs.getter
        if node.op is None:
            return lambda f, d: getter(f, d) is not MISSING
        rhs_fields = [v for v in node.values if isinstance(v, Value) and v.kind == "word" and
                      self._is_field_word(lhs, v)]
        if rhs_fields and node.op in CMP:
            return self.field_vs_field(lhs, node.op, Name(rhs_fields[0].text, rhs_fields[0].pos, rhs_fields[0].end))
        if lhs.frame_field is not None:
            ff = lhs.frame_field
            consts = [self.elem(lambda v: self.literal_for_frame_field(ff, v, node.op or "=="), e)
                      for e in node.values]
            return self.frame_test(getter, node.op, consts, ff.multi, ff.type)
        # payload field: per message, convert the literals for that message's field type
        if not lhs.companion:
            self.unit_warnings(node, lhs)
        per_msg: dict[int, tuple[str, list[object]]] = {}
        first_error: FilterError | None = None
        for mid, (kind, fd) in lhs.kinds.items():
            try:
                per_msg[mid] = (kind, [self.elem(lambda v: self.literal_for_payload(kind, fd, v, node.op or "=="), e)
                                       for e in node.values])
            except FilterError as exc:
                first_error = first_error or exc
        if not per_msg:
            assert first_error is not None
            raise first_error
        return self.payload_test(getter, node.op or "==", per_msg)

    def unit_warnings(self, node: Test, lhs: _Side) -> None:
        """A warning (`warnings`) for a number compared with a scaled field that only makes sense in its display
        unit (fields.units.looks_displayed: `GLOBAL_POSITION_INT.lat > 40.07`), naming the unit and the ways
        to say it: the companion in the display unit, or the raw number."""
        numbers = [e for e in node.values if isinstance(e, Value) and e.kind == "number"]
        numbers += [x for e in node.values if isinstance(e, Range) for x in (e.lo, e.hi) if x.kind == "number"]
        for v in numbers:
            try:
                n = _number(v)
            except ValueError:
                continue
            for kind, fd in lhs.kinds.values():
                if fd is None or not looks_displayed(fd, n):
                    continue
                s = scale_of(fd)
                cname = companion_name(fd)
                assert s is not None and cname is not None
                name = node.name.text
                owner = name.rpartition(".")[0] if "." in name else ""
                better = f"{owner}.{cname}" if owner else cname
                raw = n * s.divisor
                raw_text = str(int(raw)) if float(raw).is_integer() else f"{raw:g}"
                self.warnings.append(
                    f"{name} is sent in {fd.units} ({s.what}): {v.text} is compared with the value as sent; "
                    f"in {s.display} write {better} {node.op or '=='} {v.text} (or {name} {node.op or '=='} "
                    f"{raw_text})")
                return

    def _is_field_word(self, lhs: _Side, v: Value) -> bool:
        """A bare word on the right is a field when it names one, unless it is a value of the left field."""
        if v.text.lower() in KEYWORDS:
            return False
        ff = lhs.frame_field
        if ff is not None and (v.text in ff.choices or ff.type == IP or any(v.text == n for _, n in ff.values)):
            return False
        if self.dialect.enum_value(v.text) is not None or v.text in self.dialect.by_name:
            return False
        hit = self.registry.lookup(v.text)
        return hit is not None and not isinstance(hit, MessageDef)

    def literal_for_payload(self, kind: str, fd: FieldDef | None, v: Value, op: str) -> object:
        assert fd is not None
        if op == "matches" and kind != STR:
            raise self.error(f'"matches" needs a text field; {fd.filter_name} is not one', v)
        if op == "contains" and kind not in (STR, "array"):
            raise self.error(f'"contains" needs a text or array field; {fd.filter_name} is not one', v)
        if op == "&" and kind not in (INT,):
            raise self.error(f'"&" needs an integer field; {fd.filter_name} is not one', v)
        return self.convert(kind, v, enum=fd.enum, op=op)

    def elem(self, conv: Callable[[Value], object], e: Value | Range | Name) -> object:
        if isinstance(e, Range):
            lo, hi = conv(e.lo), conv(e.hi)
            return ("range", lo, hi)
        if isinstance(e, Name):
            raise self.error("a field cannot be used here", e)
        return conv(e)

    def field_vs_field(self, lhs: _Side, op: str, rname: Name) -> Pred:
        rhs = self.side(rname)
        assert not isinstance(rhs, MessageDef)
        lget, rget, cmp = lhs.getter, rhs.getter, CMP[op]

        def pred(f: Frame, d: dict[str, object] | None) -> bool:
            a, b = lget(f, d), rget(f, d)
            if a is MISSING or b is MISSING:
                return False
            try:
                return bool(cmp(a, b))
            except TypeError:
                return False
        return pred

    @staticmethod
    def frame_test(getter: Getter, op: str | None, consts: list[object], multi: bool, kind: str) -> Pred:
        match = matcher(op or "==", consts, kind)
        if multi:  # the field's value is a tuple of values
            if op == "!=":
                eq = matcher("==", consts, kind)
                return lambda f, d: ((v := getter(f, d)) is not MISSING
                                     and not any(eq(x) for x in cast("tuple[object, ...]", v)))
            return lambda f, d: ((v := getter(f, d)) is not MISSING
                                 and any(match(x) for x in cast("tuple[object, ...]", v)))

        def pred(f: Frame, d: dict[str, object] | None) -> bool:
            v = getter(f, d)
            return v is not MISSING and match(v)
        return pred

    @staticmethod
    def payload_test(getter: Getter, op: str, per_msg: dict[int, tuple[str, list[object]]]) -> Pred:
        matchers = {mid: (kind, matcher(op, consts, kind), matcher("==", consts, kind))
                    for mid, (kind, consts) in per_msg.items()}

        def pred(f: Frame, d: dict[str, object] | None) -> bool:
            m = matchers.get(f.msgid)
            if m is None:
                return False
            v = getter(f, d)
            if v is MISSING:
                return False
            kind, match, eq = m
            if kind == "array" and isinstance(v, list):
                if op == "contains":
                    return any(eq(x) for x in v)
                if op == "!=":
                    return not any(eq(x) for x in v)
                return any(match(x) for x in v)
            return match(v)
        return pred


@dataclass
class DisplayFilter:
    """A compiled display filter. `matches(frame)` decodes the payload only when the filter needs it."""

    text: str
    predicate: Pred
    needs_payload: bool
    names: frozenset[str]
    warnings: tuple[str, ...] = ()  # what it may not mean (Compiler.unit_warnings), for stderr

    def matches(self, frame: Frame, fields: dict[str, object] | None = None) -> bool:
        if self.needs_payload and fields is None:
            fields = decode_payload(frame)
        return self.predicate(frame, fields)

    def __call__(self, frame: Frame) -> bool:
        return self.matches(frame)


def compile_filter(text: str, dialect: Dialect, registry: FieldRegistry | None = None) -> DisplayFilter:
    """Parse and compile `text` against `dialect` (FilterError with the position on any problem)."""
    node = parse(text)
    comp = Compiler(text, dialect, registry)
    pred = comp.compile(node)
    return DisplayFilter(text, pred, comp.needs_payload, frozenset(comp.names), tuple(comp.warnings))
