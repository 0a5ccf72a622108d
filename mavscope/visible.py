"""Text a capture or a dialect chose, made safe to show on a terminal or to write into a line-based file: a
leaf module, without rich, so that the command line's stderr lines, the parameter files, the summary lines
(both engines: the native summary table carries names escaped here), the TUI and mavscope.output.console all
use the one rule.

The rule (`visible`): every character Python's `repr` escapes is written as `repr` writes it, and so is the
backslash itself. `repr` escapes the C0 controls (ESC, BEL, CR, LF...), DEL, the C1 controls (U+0080-U+009F,
among them the 8-bit CSI U+009B), format characters (bidi overrides and isolates U+202A-U+202E and
U+2066-U+2069, zero-width spaces and joiners, U+FEFF), the line and paragraph separators, lone surrogates,
private-use and unassigned code points: `\\x1b`, `\\x9b`, `\\u202e`, `\\n`, `\\udcff`. The backslash becomes
`\\\\`, so a real ESC (shown `\\x1b`) and the four characters `\\x1b` (shown `\\\\x1b`) never look alike.

Escape once, where the text is shown: a string escaped twice shows its backslashes doubled. Texts that are
made to be shown as they are (the Info column of fields/summary.py, the detail tree's labels) escape their
capture's and dialect's words as they are built (values with `repr`, which is `visible` in quotes); every
other text (notes, findings, events, error messages) carries the words as they are, quoted with `quoted`,
and the terminal's writer escapes the whole text once (cli.Env.say, output.console, the TUI's widgets).
"""

from __future__ import annotations

__all__ = ["printable", "quoted", "visible"]


def _escape(ch: str, keep_newlines: bool) -> str:
    if ch == "\\":
        return "\\\\"
    if ch.isprintable() or ch == " " or (keep_newlines and ch == "\n"):
        return ch
    return repr(ch)[1:-1]


def visible(s: str, *, keep_newlines: bool = False) -> str:
    """`s` with every character Python's `repr` would escape (controls such as ESC, format characters such
    as a right-to-left override, separators, surrogates, unassigned ones) written as `repr` writes it
    (`\\x1b`, `\\u202e`, `\\n`), and the backslash as `\\\\`. Printable text, spaces and other scripts stay
    as they are. `keep_newlines`: a line break stays one (for text a writer folds into lines of its own)."""
    if s.isprintable() and "\\" not in s:
        return s
    return "".join([_escape(ch, keep_newlines) for ch in s])


def quoted(s: str) -> str:
    """`s` in single quotes, as it is (escaped later, once, by whoever shows the text it goes into)."""
    return f"'{s}'"


def printable(s: str, *, keep_newlines: bool = False) -> str:
    """Text made of words already escaped (the Info column, the detail tree's labels) with anything still
    unprintable escaped as `visible` escapes it, its backslashes left as they are: a last guard where such
    text is shown, which changes nothing in a text built right (applied twice, it is applied once)."""
    if s.isprintable():
        return s
    return "".join([ch if ch.isprintable() or ch == " " or (keep_newlines and ch == "\n") else repr(ch)[1:-1]
                    for ch in s])
