"""Text a capture chose, made safe to show on a terminal or to write into a line-based file: a leaf
module, without rich, so that the command line's stderr lines, the parameter files and
mavscope.output.console all use the one rule."""

from __future__ import annotations


def visible(s: str, *, keep_newlines: bool = False) -> str:
    """`s` with every character Python's `repr` would escape (controls such as ESC, format characters such
    as a right-to-left override, separators, surrogates, unassigned ones) written as `repr` writes it:
    `\\x1b`, `\\u202e`, `\\n`. Printable text, spaces and other scripts stay as they are."""
    if s.isprintable():
        return s
    return "".join(
        ch if ch.isprintable() or ch == " " or (keep_newlines and ch == "\n") else repr(ch)[1:-1] for ch in s
    )
