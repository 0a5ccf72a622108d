"""Rule files (TOML, docs/rules.md) into `Rule`s: every problem a clear error with its file and line.

A file is an array of `[[rule]]` tables. Python's tomllib gives no line numbers for values, so the line of a
key is found in the text: the `[[rule]]` headers in order, and within a rule's stretch of lines the first
`KEY =` (the line of its header where the key is written some other way: an inline table, a dotted key).
Whether each filter compiles is the engine's check (it needs the dialect): `engine.RuleSet` raises the same
`RuleError`, the filter's text and a caret under the problem after the line.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable, Sequence
from pathlib import Path

from mavscope.errors import UsageError
from mavscope.notes import Severity
from mavscope.rules.model import Conditions, Per, Rule, SenderState, Threshold

PACK_DIR = Path(__file__).resolve().parent / "pack"  # the shipped pack (package data)
MAX_FILE = 1 << 20  # bytes of one rule file
MAX_RULES = 1000  # rules in one file
MAX_TEXT = 4000  # characters of a filter, a title, an explanation...
ID = re.compile(r"[a-z0-9][a-z0-9._-]{0,63}")
SEVERITIES = {s.value: s for s in (Severity.NOTE, Severity.WARN, Severity.ERROR)}
HEADER = re.compile(r"\s*\[\[\s*rule\s*\]\]")
AT_LINE = re.compile(r"\(at line (\d+), column \d+\)")
RULE_KEYS = frozenset({"id", "title", "severity", "filter", "references", "explanation", "remediation", "when",
                       "threshold"})
WHEN_KEYS = frozenset({"armed", "in_flight", "mode", "unsigned", "sender", "signature_ahead"})
THRESHOLD_KEYS = frozenset({"count", "window", "per"})
MAX_COUNT, MAX_WINDOW = 100_000, 86_400.0


class RuleError(UsageError):
    """Rule files that cannot be used: each problem as `FILE:LINE: what` (and a filter's caret lines)."""

    def __init__(self, problems: Sequence[Sequence[str]]) -> None:
        self.problems = [list(p) for p in problems]
        super().__init__("\n".join(line for p in self.problems for line in p))

    def lines(self) -> list[str]:
        return [line for p in self.problems for line in p]


class _Text:
    """Where the keys of each rule are in a file's text."""

    def __init__(self, text: str) -> None:
        self.lines = text.splitlines()
        self.headers = [i + 1 for i, line in enumerate(self.lines) if HEADER.match(line)]

    def header(self, k: int) -> int:
        return self.headers[k] if k < len(self.headers) else 1

    def key(self, k: int, key: str) -> int:
        """The line of `key =` in rule `k` (its header's line when not found)."""
        start = self.header(k)
        end = self.headers[k + 1] - 1 if k + 1 < len(self.headers) else len(self.lines)
        pattern = re.compile(rf"\s*{re.escape(key)}\s*=")
        for n in range(start, end + 1):
            if pattern.match(self.lines[n - 1]):
                return n
        return start


def _printable(s: str) -> bool:
    return all(c.isprintable() or c in "\n\t" for c in s)


class _Checker:
    def __init__(self, path: str, text: _Text) -> None:
        self.path, self.text = path, text
        self.problems: list[list[str]] = []

    def bad(self, line: int, message: str) -> None:
        self.problems.append([f"{self.path}:{line}: {message}"])

    def string(self, k: int, table: dict[str, object], key: str, *, required: bool, label: str,
               one_line: bool = False) -> str:
        value = table.get(key)
        if value is None:
            if required:
                self.bad(self.text.header(k), f"{label}: `{key}` is missing")
            return ""
        if not isinstance(value, str) or not value.strip():
            self.bad(self.text.key(k, key), f"{label}: `{key}` must be a non-empty string")
            return ""
        if len(value) > MAX_TEXT or not _printable(value) or (one_line and not value.isprintable()):
            self.bad(self.text.key(k, key), f"{label}: `{key}` must be printable text of at most {MAX_TEXT} "
                                            f"characters{' on one line' if one_line else ''}")
            return ""
        return value

    def unknown(self, k: int, table: dict[str, object], known: frozenset[str], label: str, where: str) -> None:
        for key in sorted(set(table) - known):
            self.bad(self.text.key(k, key), f"{label}: unknown key `{where}{key}` (known: {', '.join(sorted(known))})")

    def when(self, k: int, table: object, label: str) -> Conditions:
        if table is None:
            return Conditions()
        if not isinstance(table, dict):
            self.bad(self.text.key(k, "when"), f"{label}: `when` must be a table")
            return Conditions()
        self.unknown(k, table, WHEN_KEYS, label, "when.")
        flags: dict[str, bool | None] = {}
        for key in ("armed", "in_flight", "unsigned"):
            v = table.get(key)
            if v is not None and not isinstance(v, bool):
                self.bad(self.text.key(k, key), f"{label}: `when.{key}` must be true or false")
                v = None
            flags[key] = v
        mode = table.get("mode", ())
        modes = (mode,) if isinstance(mode, str) else mode
        if not isinstance(modes, (list, tuple)) or not all(isinstance(m, str) and m and _printable(m) for m in modes):
            self.bad(self.text.key(k, "mode"), f"{label}: `when.mode` must be a mode name or a list of them")
            modes = ()
        sender = table.get("sender")
        state = None
        if sender is not None:
            try:
                state = SenderState(sender)
            except ValueError:
                self.bad(self.text.key(k, "sender"), f"{label}: `when.sender` must be "
                                                     f"{' or '.join(repr(s.value) for s in SenderState)}")
        ahead = table.get("signature_ahead")
        if ahead is not None and (isinstance(ahead, bool) or not isinstance(ahead, (int, float)) or ahead < 0):
            self.bad(self.text.key(k, "signature_ahead"), f"{label}: `when.signature_ahead` must be seconds "
                                                          "(0 or more)")
            ahead = None
        return Conditions(flags["armed"], flags["in_flight"], tuple(m.upper() for m in modes), flags["unsigned"],
                          state, None if ahead is None else float(ahead))

    def threshold(self, k: int, table: object, label: str) -> Threshold | None:
        if table is None:
            return None
        if not isinstance(table, dict):
            self.bad(self.text.key(k, "threshold"), f"{label}: `threshold` must be a table")
            return None
        self.unknown(k, table, THRESHOLD_KEYS, label, "threshold.")
        count, window, per = table.get("count"), table.get("window"), table.get("per", Per.SENDER.value)
        ok = True
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_COUNT:
            self.bad(self.text.key(k, "count"), f"{label}: `threshold.count` must be a whole number 1..{MAX_COUNT:,}")
            ok = False
        if isinstance(window, bool) or not isinstance(window, (int, float)) or not 0 < window <= MAX_WINDOW:
            self.bad(self.text.key(k, "window"), f"{label}: `threshold.window` must be seconds, more than 0 and at "
                                                 f"most {MAX_WINDOW:,.0f}")
            ok = False
        if per not in {p.value for p in Per}:
            self.bad(self.text.key(k, "per"), f"{label}: `threshold.per` must be "
                                              f"{' or '.join(repr(p.value) for p in Per)}")
            ok = False
        return Threshold(int(count), float(window), Per(per)) if ok else None  # type: ignore[arg-type]

    def rule(self, k: int, table: object) -> Rule | None:
        if not isinstance(table, dict):
            self.bad(self.text.header(k), "a `[[rule]]` must be a table")
            return None
        before = len(self.problems)
        ident = self.string(k, table, "id", required=True, label=f"rule {k + 1}", one_line=True)
        if ident and not ID.fullmatch(ident):
            self.bad(self.text.key(k, "id"), f"rule {k + 1}: `id` must be 1-64 of a-z 0-9 . _ - (starting with a "
                                             "letter or digit)")
        label = f"rule {ident or k + 1}"
        self.unknown(k, table, RULE_KEYS, label, "")
        title = self.string(k, table, "title", required=True, label=label, one_line=True)
        severity = table.get("severity")
        if severity not in SEVERITIES:
            self.bad(self.text.key(k, "severity"), f"{label}: `severity` must be one of {', '.join(SEVERITIES)}")
        text = self.string(k, table, "filter", required=True, label=label)
        refs = table.get("references", [])
        if not isinstance(refs, list) or not all(isinstance(r, str) and r and len(r) <= MAX_TEXT and _printable(r)
                                                 for r in refs):
            self.bad(self.text.key(k, "references"), f"{label}: `references` must be a list of strings")
            refs = []
        explanation = self.string(k, table, "explanation", required=False, label=label)
        remediation = self.string(k, table, "remediation", required=False, label=label)
        when = self.when(k, table.get("when"), label)
        threshold = self.threshold(k, table.get("threshold"), label)
        if len(self.problems) > before:
            return None
        return Rule(ident, title, SEVERITIES[severity], text, tuple(refs), explanation, remediation, when,
                    threshold, self.path, self.text.header(k), self.text.key(k, "filter"))


def read_text(path: str, text: str) -> list[Rule]:
    """The rules of one file's text (RuleError with every problem it has)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        at = AT_LINE.search(msg)
        line = at.group(1) if at else "1"
        raise RuleError([[f"{path}:{line}: not TOML: {AT_LINE.sub('', msg).strip()}"]]) from None
    where = _Text(text)
    check = _Checker(path, where)
    for key in sorted(set(doc) - {"rule"}):
        check.bad(1, f"unknown top-level key `{key}` (a rule file is `[[rule]]` tables)")
    tables = doc.get("rule", [])
    if not isinstance(tables, list) or not tables:
        check.bad(1, "no `[[rule]]` table")
        tables = []
    if len(tables) > MAX_RULES:
        check.bad(1, f"{len(tables):,} rules: at most {MAX_RULES:,} a file")
        tables = []
    rules = [r for k, t in enumerate(tables) if (r := check.rule(k, t)) is not None]
    seen: dict[str, Rule] = {}
    for r in rules:
        if r.id in seen:
            check.bad(r.line, f"rule {r.id}: the id is used already (line {seen[r.id].line})")
        seen.setdefault(r.id, r)
    if check.problems:
        raise RuleError(check.problems)
    return rules


def read_file(path: str | Path) -> list[Rule]:
    """The rules of a file (RuleError for one that cannot be read or used)."""
    name = str(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_FILE + 1)
    except OSError as exc:
        raise RuleError([[f"{name}: {exc.strerror or exc}"]]) from None
    if len(data) > MAX_FILE:
        raise RuleError([[f"{name}: more than {MAX_FILE:,} bytes: not a rule file"]])
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise RuleError([[f"{name}:{line}: not UTF-8 text"]]) from None
    return read_text(name, text)


def rule_files(path: str | Path) -> list[Path]:
    """A rule file, or the `*.toml` files of a directory (sorted by name)."""
    p = Path(path)
    if p.is_dir():
        return sorted(f for f in p.iterdir() if f.suffix == ".toml" and f.is_file())
    return [p]


def pack_files() -> list[Path]:
    return rule_files(PACK_DIR)


def load_rules(paths: Iterable[str | Path] = (), *, default: bool = True) -> list[Rule]:
    """The shipped pack (unless `default` is False) and the rules of `paths` (files or directories), in that
    order; every problem of every file in one RuleError, a rule id used twice among them too."""
    files = (pack_files() if default else []) + [f for p in paths for f in rule_files(p)]
    files = list({f.resolve(): f for f in files}.values())  # a file named twice is read once (where first named)
    problems: list[list[str]] = []
    rules: list[Rule] = []
    for f in files:
        try:
            rules += read_file(f)
        except RuleError as exc:
            problems += exc.problems
    first: dict[str, Rule] = {}
    for r in rules:
        other = first.setdefault(r.id, r)
        if other is not r:
            problems.append([f"{r.source}:{r.line}: rule {r.id}: the id is used already ({other.source}:{other.line})"])
    if problems:
        raise RuleError(problems)
    return rules
