"""Tables written to a file or a pipe are never cut, and on a terminal of 80 columns their key columns stay whole
(issue 35, item 15).

The check is independent of the table code: the JSON document of the same command (`--json`) is the data,
and each value it holds that the table shows must appear in the text whole (written as the docs say the text
writes it: a capture's string with what Python's `repr` escapes escaped and the backslash doubled, times as
ISO-8601 UTC to the millisecond, names without their enum prefix). No cell ends in an ellipsis ('…'). Run on
every bundled capture and every real capture (../shared/real-captures), with standard output a pipe (the
test streams are not terminals) and a terminal of 80 columns (COLUMNS=80, a stream that says it is a tty).
"""

from __future__ import annotations

import io
import json
import re
from collections.abc import Callable, Iterator
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import pytest

from mavscope.cli import Env, main
from mavscope.output import grid
from mavscope.output.grid import Column, print_table
from mavscope.output.tables import console
from tests.conftest import CAPTURES, REAL_CAPTURES


def shown(s: str) -> str:
    """A capture's string as the text writes it (docs: what repr escapes, escaped; the backslash doubled)."""
    return "".join("\\\\" if ch == "\\" else ch if ch.isprintable() or ch == " " else repr(ch)[1:-1] for ch in s)


def iso(t: float | None) -> str | None:
    if t is None:
        return None
    try:
        return datetime.fromtimestamp(t, tz=timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")
    except (OverflowError, OSError, ValueError):
        return None


def party(p: list[int] | None) -> str | None:
    return None if not p else "/".join(map(str, p))


Values = Iterator[tuple[str | None, bool]]  # (a value the table shows, whether it is a key column's)


def _stats(d: dict[str, Any]) -> Values:
    for m in d["messages"]:
        yield f"{m['sysid']}/{m['compid']}", True
        yield shown(m["msgname"]), True
    for link in d["links"]:
        yield f"{link['sysid']}/{link['compid']}", True
    for c in d["conversations"]:
        yield shown(str(c["a"])), False
        yield shown(str(c["b"])), False
        yield iso(c["start"]), True
    yield from _findings(d)


def _findings(d: dict[str, Any]) -> Values:
    for f in d.get("findings", []):
        yield f["code"], True
        yield shown(f["message"]), False
        yield str(f["frames"][0]) if f["frames"] else None, False


def _commands(d: dict[str, Any]) -> Values:
    for c in d["commands"]:
        yield str(c["frames"][0]), True
        yield iso(c["time"]), True
        yield party(c["from"]), True
        yield party(c["to"]), True
        yield shown(str(c["command"])).removeprefix("MAV_CMD_"), True
        if c["answered"]:
            yield shown(str(c["result"])).removeprefix("MAV_RESULT_"), True
        for label in c["param_labels"].values():
            yield shown(label), False
    yield from _findings(d)


def _events(d: dict[str, Any]) -> Values:
    for e in d["events"]:
        yield str(e["frame"]), True
        yield iso(e["time"]), True
        yield e["kind"], True
        yield shown(e["text"]), False
    yield from _findings(d)


def _params(d: dict[str, Any]) -> Values:
    for e in d["timeline"]:
        yield str(e["frame"]), True
        yield iso(e["time"]), True
        yield shown(e["name"]), True
        yield shown(str(e["source"])), False
    yield from _findings(d)


def _mission(d: dict[str, Any]) -> Values:
    for t in d["transfers"]:
        yield shown(t["reason"]), False
        for it in t["items"]:
            yield str(it["seq"]), True
            yield it["command"].removeprefix("MAV_CMD_"), True
            yield it["frame"].removeprefix("MAV_FRAME_"), True


def _objects(d: dict[str, Any]) -> Values:
    for o in d["objects"]:
        yield str(o["number"]), True
        yield shown(o["path"] or o["name"]), False
        yield o["sha256"][:16], False
    yield from _findings(d)


def _timeline(d: dict[str, Any]) -> Values:
    for s in d["systems"]:
        for c in s["clocks"]:
            yield shown(c["source"]), True
            yield c["kind"], True
    yield from _findings(d)


COMMANDS: dict[str, Callable[[dict[str, Any]], Values]] = {
    "stats": _stats, "commands": _commands, "events": _events, "params": _params, "mission": _mission,
    "objects": _objects, "timeline": _timeline,
}


BUNDLED = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
REAL = sorted(p for p in REAL_CAPTURES.iterdir() if p.suffix != ".md") if REAL_CAPTURES.is_dir() else []


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _run(argv: list[str], out: io.StringIO, environ: dict[str, str]) -> tuple[int, str]:
    err = io.StringIO()
    status = main(argv, Env(stdout=out, stderr=err, environ=environ))
    return int(status), out.getvalue()


@pytest.mark.parametrize("capture", BUNDLED, ids=lambda p: p.name)
def test_every_value_of_the_json_is_in_the_table(capture: Path) -> None:
    _check(capture, terminal=True)


@pytest.mark.parametrize("capture", REAL, ids=lambda p: p.name)
def test_every_value_of_the_json_is_in_the_table_on_real_captures(capture: Path, real_captures: Path) -> None:
    _check(capture, terminal=False)  # (the terminal's run on the bundled captures: these take a minute each)


def _check(capture: Path, terminal: bool) -> None:
    for command, values in COMMANDS.items():
        status, doc = _run([command, str(capture), "--json"], io.StringIO(), {})
        assert status == 0, (command, capture.name)
        expected = [(v, key) for v, key in values(json.loads(doc)) if v]
        if not expected:
            continue  # (no table: "No ... in FILE")
        status, piped = _run([command, str(capture)], io.StringIO(), {})
        assert status == 0
        assert "…" not in piped, (command, capture.name)
        missing = [v for v, _ in expected if v not in piped]
        assert not missing, (command, capture.name, missing[:5])
        if not terminal:
            continue
        # a terminal of 80 columns: the key columns' values whole (never folded), nothing ellipsised
        status, narrow = _run([command, str(capture)], _Terminal(), {"COLUMNS": "80"})
        assert status == 0 and "…" not in narrow, (command, capture.name)
        plain = _no_codes(narrow)  # (colour codes sit between cells, not inside a value)
        cut = [v for v, key in expected if key and v not in plain]
        assert not cut, (command, capture.name, cut[:5])


def _no_codes(text: str) -> str:
    """The text without its SGR escape sequences (a terminal's colours)."""
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


def test_a_long_cell_is_whole_in_a_pipe_and_folded_not_cut_on_a_terminal() -> None:
    """Worked by hand: a 300-character cell beside key columns. Piped, one line holds it whole; at 80 columns
    the key columns keep their width and the long cell folds: its characters, read in order, are all there."""
    long = "".join(chr(ord("a") + i % 26) for i in range(300))
    rows = [("12345", "2026-03-14T10:00:02.000Z", long)]
    cols = [Column("frame", right=True, key=True), Column("time", key=True), Column("text")]
    piped = io.StringIO()
    print_table(console(piped, {}), cols, rows, list)
    assert any(long in line and "12345" in line for line in piped.getvalue().splitlines())
    tty = _Terminal()
    print_table(console(tty, {"COLUMNS": "80"}), cols, rows, list)
    lines = _no_codes(tty.getvalue()).splitlines()
    assert all(len(line) <= 80 for line in lines)
    assert any("12345" in line and "2026-03-14T10:00:02.000Z" in line for line in lines)
    folded = "".join(line.split("│")[3].strip() for line in lines if line.count("│") == 4)
    assert long in folded


def test_key_columns_that_cannot_fit_the_terminal_are_written_plain_and_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    """Five 20-character key columns need 111 cells with rich's borders and padding: more than 80. The table is
    then the plain layout (one line a row, the cells whole), never key cells cut to fit."""
    cells = tuple(f"{c * 19}{i}" for i, c in enumerate("abcde"))
    tty = _Terminal()
    print_table(console(tty, {"COLUMNS": "80"}), [Column(f"k{i}", key=True) for i in range(5)], [cells], list)
    body = _no_codes(tty.getvalue()).splitlines()
    assert body[-1].split() == list(cells)
    assert grid.RICH_ROWS > 1  # (the plain layout here is the terminal's width's doing, not the row count)


def test_verify_table_whole(real_captures: Path) -> None:
    """verify's per-stream table (13 columns) on the real capture whose injected frame verifies with
    SHA-256("key") (PROVENANCE.md): each stream and its key whole, piped and at 80 columns."""
    argv = ["verify", str(REAL_CAPTURES / "ap_sitl_attack1_signed_knownkey.pcap"), "--key", "passphrase:key"]
    _, doc = _run([*argv, "--json"], io.StringIO(), {})
    streams = json.loads(doc)["streams"]
    expected = [f"{s['sysid']}/{s['compid']}" for s in streams] + [k for s in streams for k in s["keys"]]
    assert len(streams) == 2 and expected
    for out, environ in ((io.StringIO(), {}), (_Terminal(), {"COLUMNS": "80"})):
        _, text = _run(argv, out, environ)
        assert "…" not in text and all(v in _no_codes(text) for v in expected), text
