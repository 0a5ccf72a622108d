"""The fleet commands say when a capture was damaged, as `read` does: `batch` (a problems column and the
count in the footer), `export` and `sql` (one line per damaged capture on stderr, capped), and which files a
directory walk passed over. The damaged files are cut by hand here: each expected offset is found by
walking the pcap, tlog or pcapng structure with `struct`, not by asking mavscope."""

from __future__ import annotations

import json
import os
import struct
import threading
from pathlib import Path

import pytest

from mavscope.export import inputs as inputs_module
from mavscope.export.inputs import Inputs, find_captures
from mavscope.mavlink.dialect import Dialect
from tests.conftest import CAPTURES, Cli

UDP = CAPTURES / "px4_sitl_udp.pcap"
TLOG = CAPTURES / "px4_sitl.tlog"
PCAPNG = CAPTURES / "px4_sitl_sll2.pcapng"
SHORT = 6  # bytes cut off the last record


def cut_pcap(dst: Path, keep: int) -> tuple[int, int]:
    """`UDP` cut SHORT bytes before the end of its record number `keep` (from 0): (that record's header
    offset, its captured length)."""
    data = UDP.read_bytes()
    assert data[:4] == bytes.fromhex("d4c3b2a1")  # little-endian pcap: 24-byte header, 16-byte record headers
    off = 24
    for _ in range(keep):
        off += 16 + struct.unpack_from("<I", data, off + 8)[0]
    incl = struct.unpack_from("<I", data, off + 8)[0]
    dst.write_bytes(data[:off + 16 + incl - SHORT])
    return off, incl


def cut_tlog(dst: Path, keep: int) -> int:
    """`TLOG` cut 7 bytes into its entry number `keep` (8-byte time, then a MAVLink frame): its offset."""
    data = TLOG.read_bytes()
    off = 0
    for _ in range(keep):
        magic, length, incompat = data[off + 8], data[off + 9], data[off + 10]
        frame = length + 12 + (13 if incompat & 1 else 0) if magic == 0xFD else length + 8
        off += 8 + frame
    dst.write_bytes(data[:off + 7])
    return off


def bad_pcapng(dst: Path) -> int:
    """`PCAPNG` with the block after the section header claiming 2 GiB: the offset of that block."""
    data = bytearray(PCAPNG.read_bytes())
    assert data[8:12] == bytes.fromhex("4d3c2b1a")  # little-endian section
    shb = struct.unpack_from("<I", data, 4)[0]
    struct.pack_into("<I", data, shb + 4, 0x7FFFFFF0)
    dst.write_bytes(bytes(data))
    return shb


def damaged(tmp_path: Path) -> dict[str, str]:
    """Three damaged captures in tmp_path/caps: name -> what the first problem must say."""
    folder = tmp_path / "caps"
    folder.mkdir()
    off, incl = cut_pcap(folder / "cut.pcap", 300)
    tlog = cut_tlog(folder / "cut.tlog", 200)
    block = bad_pcapng(folder / "bad.pcapng")
    return {"cut.pcap": f"offset {off} has {incl - SHORT} of {incl} bytes", "cut.tlog": f"offset {tlog}:",
            "bad.pcapng": f"block at offset {block}"}


def test_batch_audit_shows_the_damage_and_the_frames(cli: Cli, tmp_path: Path) -> None:
    want = damaged(tmp_path)
    status, out, err = cli("batch", str(tmp_path / "caps"), str(UDP), "--json", "--", "audit")
    assert status == 0, err
    rows = {Path(r["file"]).name: r for r in json.loads(out)["captures"]}
    for name, says in want.items():
        assert rows[name]["problems"] >= 1 and says in rows[name]["first_problem"], rows[name]
    assert rows["bad.pcapng"]["frames"] == 0
    assert rows[UDP.name]["problems"] == 0 and rows[UDP.name]["first_problem"] is None
    # frames from the audit's JSON: the generator's count for the intact capture (captures/expected.json)
    assert rows[UDP.name]["frames"] == json.loads((CAPTURES / "expected.json").read_text())[UDP.name]["frames"]
    status, out, _ = cli("batch", str(tmp_path / "caps"), str(UDP), "--", "audit")
    table = " ".join(out.split())  # (rich folds long cells over lines)
    assert "4 ok, 0 with findings, 0 error(s); 3 with problems on stderr" in table
    assert "line(s)" in table  # (the first problem beside it: rich may fold the cell over lines)


def said_the_damage(err: str, caps: list[Path], want: dict[str, str]) -> None:
    """One line on stderr per damaged capture, with its first problem; the pcapng without frames says so."""
    lines = err.splitlines()
    for path, says in zip(caps, want.values()):
        line = next(ln for ln in lines if ln.startswith(f"mavscope: {path}: "))
        assert "problem(s) reading it" in line and says in line
    assert "no MAVLink frames found" in next(ln for ln in lines if "bad.pcapng" in ln)


def test_export_says_which_captures_were_damaged(cli: Cli, tmp_path: Path) -> None:
    want = damaged(tmp_path)
    caps = [tmp_path / "caps" / n for n in want]
    status, out, err = cli("export", *map(str, caps), "--parquet", str(tmp_path / "ds"))
    assert status == 0 and "3 with problems or no frames" in out
    said_the_damage(err, caps, want)
    # the dataset keeps the count and the first problem of each capture
    q = "SELECT name, problem_count, first_problem FROM captures ORDER BY name"
    rows = json.loads(cli("sql", q, str(tmp_path / "ds"), "--json").out)
    assert [r["name"] for r in rows] == sorted(want)
    assert all(r["problem_count"] >= 1 and want[r["name"]] in r["first_problem"] for r in rows)


def test_csv_export_says_which_captures_were_damaged(cli: Cli, tmp_path: Path) -> None:
    """`-T csv` reads the captures as the Parquet export does, and says their damage the same way."""
    want = damaged(tmp_path)
    caps = [tmp_path / "caps" / n for n in want]
    status, out, err = cli("export", *map(str, caps), "-T", "csv", "-o", str(tmp_path / "csv"))
    assert status == 0 and "3 with problems or no frames" in out
    said_the_damage(err, caps, want)


def test_export_caps_its_lines(cli: Cli, tmp_path: Path) -> None:
    folder = tmp_path / "many"
    folder.mkdir()
    for k in range(13):  # 13 distinct contents, each cut in another record
        cut_pcap(folder / f"cut{k:02}.pcap", 10 + k)
    status, out, err = cli("export", str(folder), "--parquet", str(tmp_path / "ds"), "--json")
    assert status == 0
    assert all(c["problems"] == 1 for c in json.loads(out)["captures"])
    lines = err.splitlines()
    assert len(lines) == 11 and "3 more capture(s) with problems or without frames not shown (13 in all" in lines[-1]


def test_sql_over_raw_captures_says_the_damage(cli: Cli, tmp_path: Path) -> None:
    block = bad_pcapng(tmp_path / "bad.pcapng")
    status, out, err = cli("sql", "SELECT count(*) AS n FROM frames", str(tmp_path / "bad.pcapng"), "--json")
    assert status == 0 and json.loads(out) == [{"n": 0}]
    assert f"block at offset {block}" in err and "no MAVLink frames found" in err


def test_files_passed_over_are_named_when_few(cli: Cli, tmp_path: Path) -> None:
    folder = tmp_path / "flights"
    folder.mkdir()
    (folder / "flight.pcap").write_bytes(UDP.read_bytes())
    for name in ("notes.txt", "README.md"):
        (folder / name).write_text("not a capture\n")
    _, _, err = cli("batch", str(folder), "--json", "--", "stats")
    assert (f"2 file(s) in the directories are not captures and were passed over: {folder / 'README.md'}, "
            f"{folder / 'notes.txt'}") in err
    for k in range(4):
        (folder / f"more{k}.txt").write_text("no\n")
    _, _, err = cli("batch", str(folder), "--json", "--", "stats")
    assert f"6 file(s) in the directories are not captures and were passed over (e.g. {folder / 'README.md'})" in err


def test_what_is_no_regular_file_is_passed_over_and_said(cli: Cli, tmp_path: Path, dialect: Dialect,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A FIFO (a read would wait for ever: the walk runs in a thread held to 30 s), a dangling symbolic link
    and a link to a directory (os.walk follows none) are passed over and named, no longer skipped unsaid; a
    walk cut at MAX_FILES says so."""
    folder = tmp_path / "flights"
    (folder / "sub").mkdir(parents=True)
    (folder / "flight.pcap").write_bytes(UDP.read_bytes())
    os.mkfifo(folder / "pipe.pcap")
    (folder / "dangling.tlog").symlink_to(tmp_path / "nowhere")
    (folder / "sub" / "loop").symlink_to(folder)
    found: list[Inputs] = []
    walk = threading.Thread(target=lambda: found.append(find_captures([str(folder)], dialect)), daemon=True)
    walk.start()
    walk.join(30)
    assert found, "the walk blocked on the FIFO"
    (inputs,) = found
    assert inputs.captures == [str(folder / "flight.pcap")] and not inputs.stopped
    assert inputs.passed_over == [str(folder / n) for n in ("dangling.tlog", "pipe.pcap", "sub/loop")]
    monkeypatch.setattr(inputs_module, "MAX_FILES", 2)
    _, out, err = cli("batch", str(folder), "--json", "--", "stats")
    assert [r["file"] for r in json.loads(out)["captures"]] == [str(folder / "flight.pcap")]
    assert f"1 file(s) in the directories are not captures and were passed over: {folder / 'dangling.tlog'}" in err
    assert "stopped looking in the directories after 2 files: the files after those are not read" in err


def test_audit_and_verify_say_the_damage_as_read_does(cli: Cli, tmp_path: Path) -> None:
    off, incl = cut_pcap(tmp_path / "cut.pcap", 300)
    for argv in (("audit",), ("verify", "--key", "passphrase:x")):
        status, _, err = cli(*argv, str(tmp_path / "cut.pcap"))
        assert status in (0, 1) and f"offset {off} has {incl - SHORT} of {incl} bytes" in err, argv
