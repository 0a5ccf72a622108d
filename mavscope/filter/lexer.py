"""The display-filter scanner: text -> tokens (operators, words, strings), with positions for errors."""

from __future__ import annotations

import re
from dataclasses import dataclass

from mavscope.filter.errors import FilterError


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
