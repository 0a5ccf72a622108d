"""Tables past RICH_ROWS rows: plain columns, one line a row, streamed in bounded memory, nothing cut.

Expected layouts are worked out here from the cells alone: a column as wide as its widest cell (at most
PAD_LIMIT cells wide), two spaces between columns, numbers to the right. rich is not asked."""

from __future__ import annotations

import io
import tracemalloc
import unicodedata
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.output import grid
from mavscope.output.grid import PAD_LIMIT, RICH_ROWS, Column, print_table
from mavscope.output.tables import console
from tests.analysis.mission_exchange import Exchange, item_int
from tests.conftest import Cli
from tests.support.flows import T0, Sender, write_tlog


def _width(s: str) -> int:
    return sum(2 if unicodedata.east_asian_width(ch) in "WF" else 1 for ch in s)


def _cut(line: str, widths: list[int]) -> list[str]:
    """The line's cells at the column offsets the widths give (two spaces between columns)."""
    cells, at, i = [], 0, 0
    for w in widths[:-1]:
        start = i
        while at < w and i < len(line):
            at += _width(line[i])
            i += 1
        cells.append(line[start:i])
        assert line[i:i + 2] == "  ", line  # the gap between columns
        i += 2
        at = 0
    cells.append(line[i:])
    return cells


CELL = st.text(st.sampled_from("ab9 -/.:_\x1b\n\t漢字é"), max_size=12).map(str.strip)


@settings(max_examples=150, deadline=None)
@given(rows=st.lists(st.tuples(CELL, CELL, CELL), min_size=1, max_size=20), right=st.booleans())
def test_plain_columns_give_back_every_cell(rows: list[tuple[str, str, str]], right: bool) -> None:
    out = io.StringIO()
    cols = [Column("a"), Column("bb", right=right), Column("c")]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(grid, "RICH_ROWS", 0)
        print_table(console(out, {}), cols, rows, list, title="T")
    lines = out.getvalue().split("\n")
    assert lines[0] == "T" and lines[-1] == "" and len(lines) == len(rows) + 4  # title, head, rule, rows, end
    # what Python's repr escapes, escaped: one row, one line
    shown = [tuple("".join(ch if ch.isprintable() or ch == " " else repr(ch)[1:-1] for ch in cell) for cell in row)
             for row in rows]
    widths = [max(_width(c), *(_width(r[j]) for r in shown)) for j, c in enumerate(("a", "bb", "c"))]
    head = _cut(lines[1], widths)
    assert head[0] == "a".ljust(widths[0]) and head[1] == ("bb".rjust if right else "bb".ljust)(widths[1])
    assert lines[2] == "  ".join("-" * w for w in widths)
    for line, row in zip(lines[3:-1], shown):
        a, b, c = _cut(line.ljust(sum(widths) + 4), widths)  # the line's trailing spaces are not written
        assert line == line.rstrip() and (a.rstrip(" "), b.strip(" "), c.rstrip(" ")) == row
        pad = " " * (widths[1] - _width(row[1]))
        assert b == (pad + row[1] if right else row[1] + pad)


def test_a_long_cell_runs_on_uncut_and_widens_no_other_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(grid, "RICH_ROWS", 0)
    out = io.StringIO()
    long = "x" * (PAD_LIMIT * 10)
    print_table(console(out, {}), [Column("n", right=True), Column("text"), Column("end")],
                [("1", "short", "e"), ("2", long, "e")], list)
    head, rule, short, big = out.getvalue().splitlines()
    assert short == "1  short" + " " * (PAD_LIMIT - 5) + "  e"  # padded to PAD_LIMIT, not to the long cell
    assert big == f"2  {long}  e" and len(head) == len(rule) == len(short) + 2


def test_plain_layout_streams_in_bounded_memory() -> None:
    """rich's layout took about 13 KB a row; the plain one holds a chunk of lines at a time."""
    rows = [(str(i), f"2024-01-01T00:00:{i % 60:02d}.000Z", "255/190", "1/1", "COMPONENT_ARM_DISARM",
             "param1 1, param2 21196", "ACCEPTED", "12.5", "0") for i in range(RICH_ROWS * 20)]
    out = io.StringIO()
    con = console(out, {})
    cols = [Column(str(j)) for j in range(9)]
    tracemalloc.start()
    try:
        print_table(con, cols, rows, list)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    text = out.getvalue()
    assert text.count("\n") == len(rows) + 2
    assert peak - len(text) * 2 < 1_000_000  # the output itself (a StringIO of 1-2 bytes a char) aside


def test_commands_past_rich_rows_are_one_line_each(cli: Cli, tmp_path: Path) -> None:
    """RICH_ROWS + 200 commands, each to its own target (none a retry of another), the first half
    acknowledged ACCEPTED by their targets: every command is its line, in the order sent, record first.
    Then RICH_ROWS + 1 ACKs no command waits for: a line each, however narrow the console."""
    x = Exchange()
    n = RICH_ROWS + 200
    records = []
    for i in range(n):
        target = (1 + i // 200, 1 + i % 200)
        records.append(x.send("gcs", "COMMAND_LONG", *target, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    for i in range(n // 2):
        x.veh.srcSystem, x.veh.srcComponent = 1 + i // 200, 1 + i % 200
        x.send("veh", "COMMAND_ACK", 400, 0, 0, 0, 255, 190)
    orphans = []
    for i in range(RICH_ROWS + 1):  # ACKs from systems no command went to: each its own line
        x.veh.srcSystem, x.veh.srcComponent = 20 + i // 200, 1 + i % 200
        orphans.append((x.send("veh", "COMMAND_ACK", 400, 4, 0, 0, 255, 190), x.veh.srcSystem, x.veh.srcComponent))
    status, out, err = cli("commands", x.tlog(tmp_path / "many.tlog"))
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("Commands (") and lines[1].split()[:3] == ["frame", "time", "from"]
    rows = lines[3:3 + n]
    assert [int(r.split()[0]) for r in rows] == records
    assert all(r.startswith(" ") for r in rows[:9])  # the record column is right-aligned
    assert [("ACCEPTED" in r, "UNANSWERED" in r) for r in rows] == [(i < n // 2, i >= n // 2) for i in range(n)]
    assert lines[3 + n] == f"{n} commands, {n - n // 2} unanswered, {len(orphans)} ACKs matching no command"
    # result 4 is MAV_RESULT_FAILED
    assert lines[4 + n:] == [f"  frame {r}: ACK MAV_CMD_COMPONENT_ARM_DISARM MAV_RESULT_FAILED from {s}/{c}"
                             for r, s, c in orphans]


def test_mission_past_rich_rows_is_one_line_a_transfer_and_an_item(cli: Cli, tmp_path: Path) -> None:
    """RICH_ROWS // 2 + 100 uploads of 1 item each (MISSION_COUNT, MISSION_REQUEST_INT, MISSION_ITEM_INT,
    MISSION_ACK ACCEPTED, built with pymavlink; command 16 is MAV_CMD_NAV_WAYPOINT) are more than RICH_ROWS
    transfers and items together: each transfer is its line, then its heading, rule and item line; nothing
    wraps whatever the line's length."""
    x = Exchange()
    n = RICH_ROWS // 2 + 100
    for i in range(n):
        x.send("gcs", "MISSION_COUNT", 1, 1, 1, 0)
        x.send("veh", "MISSION_REQUEST_INT", 255, 190, 0, 0)
        item_int(x, "gcs", (1, 1), 0, 16, 47.0 + i * 1e-4, 8.0, 10.0 + i)
        x.send("veh", "MISSION_ACK", 255, 190, 0, 0)
        x.wait(5)  # each upload its own transfer
    status, out, err = cli("mission", x.tlog(tmp_path / "uploads.tlog"))
    assert status == 0, err
    lines = out.splitlines()
    assert len(lines) == 4 * n
    for i in range(n):
        head, cols, rule, item = lines[4 * i: 4 * i + 4]
        assert head.startswith(f"Transfer {i + 1}: upload ") and head.endswith(f"frames {4 * i + 1}-{4 * i + 4}")
        assert ", 1 items, complete: " in head
        assert cols.split()[:3] == ["seq", "command", "frame"] and set(rule) <= {"-", " "}
        assert item.split()[:2] == ["0", "NAV_WAYPOINT"] and f"{47.0 + i * 1e-4:.7f}°" in item


def test_timeline_past_rich_rows_lays_out_every_system_plain(cli: Cli, tmp_path: Path) -> None:
    """6 systems x 200 components, each sending one GLOBAL_POSITION_INT (built with pymavlink) whose
    time_boot_ms is its own: 1,200 boot clocks of one sample, 200 per system, so no table has more than
    RICH_ROWS rows but all of them together do. Each system is its title, heading, rule and one line a
    component in component order; rich's 250 small tables took timeline 29.5 s on 50,000 such clocks."""
    entries = []
    for i in range(1200):
        sysid, compid = 1 + i // 200, 1 + i % 200
        msg = v2.MAVLink_global_position_int_message(1000 * (i + 1), 0, 0, 0, 0, 0, 0, 0, 0)
        entries.append((T0 + i * 0.01, Sender(sysid, compid).pack(msg)))
    status, out, err = cli("timeline", write_tlog(tmp_path, entries))
    assert status == 0, err
    lines = out.splitlines()
    start = lines.index("System 1")  # after the capture's line (rich's: wrapped to the console's width)
    assert lines[0].startswith("Capture ") and start <= 3
    for k in range(6):
        block = lines[start + 203 * k: start + 203 * (k + 1)]
        assert block[0] == f"System {k + 1}" and block[1].split()[:3] == ["comp", "clock", "kind"]
        assert [r.split()[:4] for r in block[3:]] == [[str(c), "time_boot_ms", "boot", "1"] for c in range(1, 201)]
    assert len(lines) == start + 6 * 203
