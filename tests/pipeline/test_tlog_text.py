"""Telemetry logs whose entries hold text, not MAVLink (MAVProxy logs a SITL's console one byte an entry).

Expected values come from how the file is built here, entry by entry: which entries are text, what they
spell, and which entries hold the pymavlink-encoded frames.
"""

from __future__ import annotations

from pathlib import Path

from mavscope.capture.detect import open_capture
from mavscope.pipeline import textrun
from tests.conftest import Cli
from tests.support.builders import tlog_spaced
from tests.support.pmav import heartbeat, mav2

T0 = 1_746_714_528_149_261  # µs


def test_a_tlog_that_starts_with_console_text_is_a_tlog(tmp_path: Path, cli: Cli) -> None:
    mav = mav2()
    text = [bytes([c]) for c in b"\nInit ArduRover\n"]
    entries = text + [heartbeat(mav), b"BAD", heartbeat(mav), heartbeat(mav)]
    path = tmp_path / "console.tlog"
    path.write_bytes(tlog_spaced(entries, T0, 20))  # 20 µs apart
    with open_capture(path) as reader:
        assert reader.kind == "tlog"
        records = list(reader)
    assert [r.data for r in records] == entries and not any(r.notes for r in records)
    frames = cli.jsonl(path)
    assert [f["frame"] for f in frames] == [len(text) + 1, len(text) + 3, len(text) + 4]
    status, _, err = cli("read", path, "-q")
    assert status == 0
    bad_offset = (len(text) + 1) * 8 + len(text) + len(entries[len(text)]) + 8  # after the text and the frame
    why = "(text a logger wrote, or data it could not parse)"
    assert err.splitlines() == [
        f"mavscope: {path}: record 1: offset 8: tlog entries 1-{len(text)}: {len(text)} bytes that are not MAVLink "
        + why + r": '\nInit ArduRover\n'",
        f"mavscope: {path}: record {len(text) + 2}: offset {bad_offset}: tlog entry {len(text) + 2}: 3 bytes that are "
        f"not MAVLink {why}: 'BAD'",
    ]


def test_a_long_text_run_is_reported_in_bounded_pieces(tmp_path: Path, cli: Cli) -> None:
    per_entry = 16
    n = textrun.MAX_BYTES // per_entry + 2  # one entry past a full run
    path = tmp_path / "chatty.tlog"
    path.write_bytes(tlog_spaced([b"x" * per_entry] * n + [heartbeat(mav2())], T0, 20))
    status, out, err = cli("read", path)
    assert status == 0 and out.count("HEARTBEAT") == 1
    lines = err.splitlines()
    full = textrun.MAX_BYTES // per_entry
    assert len(lines) == 2, err
    assert f"tlog entries 1-{full}: {textrun.MAX_BYTES} bytes" in lines[0] and lines[0].endswith("...")
    assert f"tlog entries {full + 1}-{n}: {(n - full) * per_entry} bytes" in lines[1]
