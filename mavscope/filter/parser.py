"""The display-filter grammar: tokens -> an AST of tests, negations and boolean operators.

    expr    := and ( ("or" | "||") and )*
    and     := not ( ("and" | "&&") not )*
    not     := ("not" | "!") not | primary
    primary := "(" expr ")" | NAME [ relop value | "&" value | "contains" value | "matches" value
                                     | "in" "{" element ( [","] element )* "}" ]
    relop   := "==" | "!=" | "<" | "<=" | ">" | ">=" | "eq" | "ne" | "lt" | "le" | "gt" | "ge"
    element := value | NUMBER ".." NUMBER
"""

from __future__ import annotations

from dataclasses import dataclass

from mavscope.filter.errors import MAX_DEPTH, FilterError
from mavscope.filter.lexer import _NUMBER, _WORD_OPS, KEYWORDS, Token, tokenize


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
