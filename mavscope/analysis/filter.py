"""Display filters: a Wireshark-style language over the field registry, compiled once, run per frame.

    compile_filter('COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH', dialect).matches(frame)

A tokenizer, a recursive-descent parser to an AST, and a compiler that turns the AST into nested
closures over the registry's accessors (mavscope.analysis.fields). No `eval`. Literals are converted
once at compile time (enum names to numbers through the dialect, addresses to networks, regexes
compiled), and the payload is decoded per frame only when the filter names a payload field.

Grammar (lowest precedence first):

    expr    := and ( ("or" | "||") and )*
    and     := not ( ("and" | "&&") not )*
    not     := ("not" | "!") not | primary
    primary := "(" expr ")" | NAME [ relop value | "&" value | "contains" value | "matches" value
                                     | "in" "{" element ( [","] element )* "}" ]
    relop   := "==" | "!=" | "<" | "<=" | ">" | ">=" | "eq" | "ne" | "lt" | "le" | "gt" | "ge"
    element := value | NUMBER ".." NUMBER

A NAME alone tests that the frame has the field (a bare message name: that the frame is that message).
A comparison on a field the frame does not have is false, `!=` included (Wireshark semantics).
Every error is a FilterError carrying the position and length of the offending text.
"""

from __future__ import annotations

import difflib
import ipaddress
import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import cast

from mavscope.analysis.fields import (
    BYTES,
    FLOAT,
    INT,
    IP,
    MISSING,
    NONE,
    STR,
    FieldRegistry,
    FrameField,
    PayloadField,
    payload_value,
)
from mavscope.errors import MavscopeError
from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef
from mavscope.mavlink.frame import Frame, decode_payload

MAX_DEPTH = 64  # parentheses nested deeper than this are refused (no RecursionError on hostile input)


class FilterError(MavscopeError):
    """A display filter that cannot be compiled: the message, and where in the text the problem is."""

    def __init__(self, message: str, text: str, position: int, length: int = 1) -> None:
        self.message = message
        self.text = text
        self.position = max(0, min(position, len(text)))
        self.length = max(1, length)
        super().__init__(self.render())

    def render(self) -> str:
        shown = "".join(" " if c in "\t\r\n\v\f" else c for c in self.text)
        caret = " " * self.position + "^" + "~" * (self.length - 1)
        return f"filter error: {self.message}\n  {shown}\n  {caret}"


# --------------------------------------------------------------------------------------------------
# Tokens
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Token:
    kind: str  # "op", "word", "string", "eof"
    text: str  # the operator, the word, or the decoded string
    pos: int
    end: int


_OPS = ("==", "!=", "<=", ">=", "&&", "||", "<", ">", "!", "(", ")", "{", "}", ",", "&", "~")
_WORD_START = re.compile(r"[A-Za-z0-9_.:\-]")
_WORD = re.compile(r"[A-Za-z0-9_.:\-/]+")
_NUMBER = re.compile(r"-?(?:0[xX][0-9a-fA-F]+|(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "0": "\0", "\\": "\\", '"': '"', "'": "'"}
_WORD_OPS = {"eq": "==", "ne": "!=", "lt": "<", "le": "<=", "gt": ">", "ge": ">=", "and": "&&", "or": "||",
             "not": "!"}
KEYWORDS = frozenset(_WORD_OPS) | {"contains", "matches", "in"}


def tokenize(text: str) -> list[Token]:
    tokens: list[Token] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c.isspace():
            i += 1
            continue
        if c in "\"'":
            start, i, buf = i, i + 1, []
            while True:
                if i >= n:
                    raise FilterError("unterminated string", text, start, n - start)
                ch = text[i]
                if ch == c:
                    i += 1
                    break
                if ch == "\\":
                    if i + 1 >= n:
                        raise FilterError("unterminated string", text, start, n - start)
                    e = text[i + 1]
                    if e == "x":
                        hexpart = text[i + 2 : i + 4]
                        if len(hexpart) != 2 or not all(h in "0123456789abcdefABCDEF" for h in hexpart):
                            raise FilterError("bad \\x escape: two hex digits expected", text, i, 2)
                        buf.append(chr(int(hexpart, 16)))
                        i += 4
                        continue
                    if e not in _ESCAPES:
                        raise FilterError(f"unknown escape \\{e}", text, i, 2)
                    buf.append(_ESCAPES[e])
                    i += 2
                    continue
                buf.append(ch)
                i += 1
            tokens.append(Token("string", "".join(buf), start, i))
            continue
        op = next((o for o in _OPS if text.startswith(o, i)), None)
        if op is not None:
            tokens.append(Token("op", op, i, i + len(op)))
            i += len(op)
            continue
        if _WORD_START.match(c):
            m = _WORD.match(text, i)
            assert m is not None
            tokens.append(Token("word", m.group(), i, m.end()))
            i = m.end()
            continue
        raise FilterError(f"unexpected character {c!r}", text, i, 1)
    tokens.append(Token("eof", "", n, n))
    return tokens


# --------------------------------------------------------------------------------------------------
# AST
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Value:
    kind: str  # "number", "string", "word"
    text: str
    pos: int
    end: int


@dataclass(frozen=True, slots=True)
class Range:
    lo: Value
    hi: Value
    pos: int
    end: int


@dataclass(frozen=True, slots=True)
class Name:
    text: str
    pos: int
    end: int


@dataclass(frozen=True, slots=True)
class Test:
    name: Name
    op: str | None  # None: existence; "==", "!=", "<", "<=", ">", ">=", "&", "contains", "matches", "in"
    values: tuple[Value | Range | Name, ...] = ()


@dataclass(frozen=True, slots=True)
class Not:
    arg: Node


@dataclass(frozen=True, slots=True)
class BoolOp:
    op: str  # "&&" or "||"
    args: tuple[Node, ...]


Node = Test | Not | BoolOp


class Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = tokenize(text)
        self.i = 0
        self.depth = 0

    def peek(self) -> Token:
        return self.tokens[self.i]

    def next(self) -> Token:
        tok = self.tokens[self.i]
        if tok.kind != "eof":
            self.i += 1
        return tok

    def error(self, message: str, tok: Token) -> FilterError:
        if tok.kind == "eof":
            return FilterError(f"unexpected end of filter: {message}", self.text, len(self.text), 1)
        return FilterError(message, self.text, tok.pos, tok.end - tok.pos)

    def op_of(self, tok: Token) -> str | None:
        if tok.kind == "op":
            return tok.text
        if tok.kind == "word":
            return _WORD_OPS.get(tok.text.lower(), tok.text.lower() if tok.text.lower() in KEYWORDS else None)
        return None

    def parse(self) -> Node:
        if self.peek().kind == "eof":
            raise FilterError("empty filter", self.text, 0, 1)
        node = self.expr()
        tok = self.peek()
        if tok.kind != "eof":
            raise self.error(f"unexpected {tok.text!r}: expected and, or or the end of the filter", tok)
        return node

    def expr(self) -> Node:
        args = [self.conj()]
        while self.op_of(self.peek()) == "||":
            self.next()
            args.append(self.conj())
        return args[0] if len(args) == 1 else BoolOp("||", tuple(args))

    def conj(self) -> Node:
        args = [self.neg()]
        while self.op_of(self.peek()) == "&&":
            self.next()
            args.append(self.neg())
        return args[0] if len(args) == 1 else BoolOp("&&", tuple(args))

    def neg(self) -> Node:
        count = 0
        while self.op_of(self.peek()) == "!":
            self.next()
            count += 1
        node = self.primary()
        return Not(node) if count % 2 else node  # "not not x" is x

    def primary(self) -> Node:
        tok = self.next()
        if tok.kind == "op" and tok.text == "(":
            self.depth += 1
            if self.depth > MAX_DEPTH:
                raise self.error(f"parentheses nested deeper than {MAX_DEPTH}", tok)
            node = self.expr()
            close = self.next()
            if not (close.kind == "op" and close.text == ")"):
                raise self.error(f"expected ')' to close the '(' at column {tok.pos + 1}", close)
            self.depth -= 1
            return node
        if tok.kind != "word" or tok.text.lower() in KEYWORDS:
            raise self.error("expected a field name, a message name, 'not' or '('", tok)
        name = Name(tok.text, tok.pos, tok.end)
        op = self.op_of(self.peek())
        if op in ("==", "!=", "<", "<=", ">", ">=", "&", "contains", "matches", "~"):
            self.next()
            return Test(name, "matches" if op == "~" else op, (self.value(),))
        if op == "in":
            self.next()
            return Test(name, "in", self.set_values())
        return Test(name, None)

    def value(self) -> Value | Name:
        tok = self.next()
        if tok.kind == "string":
            return Value("string", tok.text, tok.pos, tok.end)
        if tok.kind == "word" and tok.text.lower() not in KEYWORDS:
            if _NUMBER.fullmatch(tok.text):
                return Value("number", tok.text, tok.pos, tok.end)
            return Value("word", tok.text, tok.pos, tok.end)
        raise self.error("expected a value (number, string, name)", tok)

    def set_values(self) -> tuple[Value | Range | Name, ...]:
        tok = self.next()
        if not (tok.kind == "op" and tok.text == "{"):
            raise self.error("expected '{' after 'in'", tok)
        out: list[Value | Range | Name] = []
        while True:
            tok = self.peek()
            if tok.kind == "op" and tok.text == "}":
                self.next()
                break
            if tok.kind == "op" and tok.text == "," and out:
                self.next()
                continue
            if tok.kind == "word" and ".." in tok.text:
                self.next()
                lo, _, hi = tok.text.partition("..")
                if not (_NUMBER.fullmatch(lo) and _NUMBER.fullmatch(hi)):
                    raise self.error("a range is NUMBER..NUMBER", tok)
                mid = tok.pos + len(lo)
                out.append(Range(Value("number", lo, tok.pos, mid), Value("number", hi, mid + 2, tok.end),
                                 tok.pos, tok.end))
                continue
            out.append(self.value())
        if not out:
            raise self.error("empty set", tok)
        return tuple(out)


def parse(text: str) -> Node:
    """The AST of a filter (FilterError if it is not well formed)."""
    return Parser(text).parse()


# --------------------------------------------------------------------------------------------------
# Compilation
# --------------------------------------------------------------------------------------------------

Pred = Callable[[Frame, "dict[str, object] | None"], bool]
Getter = Callable[[Frame, "dict[str, object] | None"], object]
_NO = object()  # a literal that cannot match this message's field

# typeshed types the ordering operators for comparable values only; here they get any field value and
# the callers catch the TypeError of a mismatch.
_CMP: dict[str, Callable[[object, object], bool]] = {
    "==": operator.eq, "!=": operator.ne,
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,  # type: ignore[dict-item]
}


def _number(v: Value) -> int | float:
    t = v.text
    neg = t.startswith("-")
    body = t[1:] if neg else t
    if body[:2].lower() == "0x":
        n: int | float = int(body, 16)
    elif any(c in body for c in ".eE"):
        n = float(body)
    else:
        n = int(body)
    return -n if neg else n


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
    frame_field: FrameField | None = None


class Compiler:
    def __init__(self, text: str, dialect: Dialect, registry: FieldRegistry | None = None) -> None:
        self.text = text
        self.dialect = dialect
        self.registry = registry or FieldRegistry(dialect)
        self.needs_payload = False
        self.names: set[str] = set()

    def error(self, message: str, node: Name | Value | Range) -> FilterError:
        return FilterError(message, self.text, node.pos, node.end - node.pos)

    # names --------------------------------------------------------------------------------------

    def resolve(self, name: Name) -> FrameField | PayloadField | MessageDef:
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
        if isinstance(hit, FrameField):
            get = hit.get
            return _Side(name, lambda f, _d: get(f), False, frame_field=hit)
        self.needs_payload = True
        defs = hit.defs
        kinds: dict[int, tuple[str, FieldDef | None]] = {mid: (_field_kind(fd), fd) for mid, fd in defs.items()}
        return _Side(name, lambda f, d: payload_value(defs, f, d), True, kinds)

    # literals -----------------------------------------------------------------------------------

    def convert(self, kind: str, v: Value, *, enum: str = "", choices: tuple[str, ...] = (),
                msgid_field: bool = False, op: str = "==") -> object:
        """A literal as a value comparable with a field of `kind` (FilterError if it cannot be)."""
        if kind in (INT, FLOAT, "array"):
            if v.kind == "number":
                return _number(v)
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
                raise self.error(f'"{v.text}" is not a number, nor an enum name in the loaded dialects', v)
            raise self.error(f'"{v.text}" is not a number', v)
        if kind == STR:
            if op == "matches":
                try:
                    return re.compile(v.text)
                except Exception as exc:  # re.error, OverflowError, RecursionError on hostile patterns
                    raise self.error(f"bad regular expression: {exc}", v) from None
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

    def convert_time(self, v: Value) -> float:
        if v.kind == "number":
            return float(_number(v))
        try:
            dt = datetime.fromisoformat(v.text.replace("Z", "+00:00"))
        except ValueError:
            raise self.error(f'"{v.text}" is neither Unix seconds nor an ISO-8601 time', v) from None
        if dt.tzinfo is None:
            dt = dt.replace(tzinfo=timezone.utc)
        return dt.timestamp()

    def literal_for_frame_field(self, ff: FrameField, v: Value, op: str) -> object:
        if ff.type == NONE:
            raise self.error(f'"{ff.name}" only tells whether a frame has it: use it alone, without a comparison',
                             v)
        if ff.name in ("frame.time", "signature.time"):
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
        return self.convert(kind, v, enum=ff.enum, choices=ff.choices, msgid_field=ff.name == "mavlink.msgid", op=op)

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
        if rhs_fields and node.op in _CMP:
            return self.field_vs_field(lhs, node.op, Name(rhs_fields[0].text, rhs_fields[0].pos, rhs_fields[0].end))
        if lhs.frame_field is not None:
            ff = lhs.frame_field
            consts = [self.elem(lambda v: self.literal_for_frame_field(ff, v, node.op or "=="), e)
                      for e in node.values]
            return self.frame_test(getter, node.op, consts, ff.multi, ff.type)
        # payload field: per message, convert the literals for that message's field type
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

    def _is_field_word(self, lhs: _Side, v: Value) -> bool:
        """A bare word on the right is a field when it names one, unless it is a value of the left field."""
        if v.text.lower() in KEYWORDS:
            return False
        ff = lhs.frame_field
        if ff is not None and (v.text in ff.choices or ff.type == IP):
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
        lget, rget, cmp = lhs.getter, rhs.getter, _CMP[op]

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
        match = _matcher(op or "==", consts, kind)
        if multi:  # the field's value is a tuple of values
            if op == "!=":
                eq = _matcher("==", consts, kind)
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
        matchers = {mid: (kind, _matcher(op, consts, kind), _matcher("==", consts, kind))
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


def _matcher(op: str, consts: list[object], kind: str) -> Callable[[object], bool]:
    """A test of one field value against the converted literal(s)."""
    if op == "in":
        singles = [c for c in consts if not (isinstance(c, tuple) and c and c[0] == "range")]
        ranges = [(c[1], c[2]) for c in consts if isinstance(c, tuple) and c and c[0] == "range"]
        eqs = [_matcher("==", [c], kind) for c in singles]

        def in_(v: object) -> bool:
            if any(e(v) for e in eqs):
                return True
            try:
                return any(lo <= v <= hi for lo, hi in ranges)
            except TypeError:
                return False
        return in_
    c = consts[0]
    if op == "matches":
        search = c.search  # type: ignore[attr-defined]
        return lambda v: isinstance(v, str) and search(v) is not None
    if op == "contains":
        if kind == "array":
            return lambda v: v == c
        return lambda v: isinstance(v, (str, bytes)) and type(v) is type(c) and c in v  # type: ignore[operator]
    if op == "&":
        return lambda v: isinstance(v, int) and bool(v & c)  # type: ignore[operator]
    if isinstance(c, (ipaddress.IPv4Network, ipaddress.IPv6Network)):
        net = c
        if op == "==":
            return lambda v: v in net
        return lambda v: v not in net
    cmp = _CMP[op]
    if isinstance(c, float) and math.isnan(c):
        return lambda v: False

    def m(v: object) -> bool:
        try:
            return bool(cmp(v, c))
        except TypeError:
            return False
    return m


@dataclass
class DisplayFilter:
    """A compiled display filter. `matches(frame)` decodes the payload only when the filter needs it."""

    text: str
    predicate: Pred
    needs_payload: bool
    names: frozenset[str]

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
    return DisplayFilter(text, pred, comp.needs_payload, frozenset(comp.names))
