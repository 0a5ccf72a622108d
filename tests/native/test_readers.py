"""The native walker reads capture files as the Python readers do (mavscope/capture/): with pread, a window
at a time, never memory-mapped.

Expected output is the pure-Python path's (the reference), on captures built here: records crossing
window boundaries and damaged files (whatever the window), a file that shrinks before and while it is
walked (a note, never SIGBUS), pcapng times outside 1970..9999, and tlog entries of console text between
frames written natively.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from mavscope.mavlink.dialect import Dialect
from tests.capture.test_hostile_shrink import KINDS, _damage, make_capture
from tests.conftest import ROOT, Cli
from tests.native import build as nh
from tests.native.engines import native_output, pure_output, same
from tests.support.builders import tlog_spaced
from tests.support.pmav import heartbeat, mav2

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

SHRANK = "the file shrank while it was read"


@pytest.mark.parametrize("kind", KINDS)
def test_the_read_window_changes_nothing(tmp_path: Path, kind: str, dialect: Dialect) -> None:
    """Records and blocks crossing window boundaries, resynchronisation scanning across windows."""
    path = tmp_path / f"capture.{kind}"
    make_capture(path, kind)
    clean = path.read_bytes()
    for seed in range(4):
        path.write_bytes(clean if seed == 0 else _damage(clean, seed))
        expected = pure_output(path, dialect)
        assert expected[0].count(b"\n") > 1000
        for window in (64, 333, 4096, 1 << 20):
            assert native_output(path, dialect, window=window)[:2] == expected, (seed, window)


@contextmanager
def truncated_when_opened(path: Path, size: int, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The capture is cut to `size` bytes right after a reader (or the native walker) opened it: both see a
    file that shrank before their first read."""
    import mavscope.capture.reader as reader
    import mavscope.native.walk as native

    original = reader.open_file

    def open_then_truncate(p: str | os.PathLike[str]) -> tuple[str, object, int]:
        opened = original(p)
        os.truncate(path, size)
        return opened  # type: ignore[return-value]

    content = path.read_bytes()
    monkeypatch.setattr(reader, "open_file", open_then_truncate)
    monkeypatch.setattr(native, "open_file", open_then_truncate)
    yield
    path.write_bytes(content)


@pytest.mark.parametrize("kind", KINDS)
def test_a_file_that_shrank_after_it_was_opened(tmp_path: Path, kind: str, dialect: Dialect,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / f"shrinking.{kind}"
    make_capture(path, kind)
    size = path.stat().st_size
    with truncated_when_opened(path, size // 3, monkeypatch):
        expected = pure_output(path, dialect)
    with truncated_when_opened(path, size // 3, monkeypatch):
        got = native_output(path, dialect)
    assert got[:2] == expected
    assert SHRANK in expected[1] or SHRANK in expected[0].decode()  # on stderr, or a frame's note


def walk_while_shrinking(path: str) -> None:
    """Walk a capture in small batches, reading 4 KiB at a time; after the first batch cut the file to a
    third: the walk goes on to the end without a fault, and ends with the shrink note; nothing is made up."""
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.native.walk import NativeWalk

    dialect = load_dialect()
    full = Path(path).read_bytes()
    texts, notes = [], []
    with NativeWalk(path, dialect, set(), set(), window=4096) as walk:
        for n, batch in enumerate(walk.batches(limit=4096)):
            if n == 1:
                os.truncate(path, len(full) // 3)
            if batch.text is not None:
                texts.append(bytes(batch.text))
            if batch.record is not None:
                rec = batch.record
                assert rec.data == full[rec.offset:rec.offset + len(rec.data)]
                notes += [n.message for n in rec.notes]
        assert walk.size < len(full)
    assert any(SHRANK in n for n in notes), notes[-3:]
    assert len(texts) > 1 or not texts  # a raw stream is handed back whole: no text
    print("OK")


@pytest.mark.parametrize("kind", KINDS)
def test_a_file_that_shrinks_during_the_walk(tmp_path: Path, kind: str) -> None:
    path = tmp_path / f"shrinking.{kind}"
    make_capture(path, kind)
    code = f"from tests.native.test_readers import walk_while_shrinking as w; w({str(path)!r})"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"exit status {proc.returncode} (-7/135: SIGBUS)\n{proc.stdout}\n{proc.stderr}"
    assert "OK" in proc.stdout


def test_pcapng_times_outside_the_calendar(tmp_path: Path, cli: Cli, dialect: Dialect) -> None:
    """Interface 0: microseconds and if_tsoffset -2**40 s (a time C computes: before 1970); interface 1:
    tsresol 10**-20 and if_tsoffset 2**40 s (units above 2**64: Python computes the time; after 9999)."""
    md = dialect.by_name["HEARTBEAT"]
    hb = nh.frame_v2(md, md.id, bytes(9), 0, 1, 1)
    lo = b"\x7f\0\0\1"
    pkt = nh.link("ethernet", nh.ipv4(lo, lo, 17, nh.udp(14550, 14550, hb)), False)
    ticks = 1_700_000_000 * 10**6
    ifaces = [(1, None, -(2**40)), (1, 20, 2**40), (1, None, 0)]
    path = tmp_path / "times.pcapng"
    path.write_bytes(nh.pcapng(ifaces, [(0, ticks, pkt), (1, ticks, pkt), (2, ticks, pkt)]))
    result = same(cli, path)
    notes = [line.split('"notes":')[1] for line in result.out.splitlines()]
    t0 = ticks / 10**6 - 2**40
    t1 = ticks / 10**20 + 2**40
    assert f"packet time {t0:.6g} s since 1970 (interface 0: if_tsoffset {-(2**40)} s, 1000000 ticks/s)" in notes[0]
    assert (f"packet time {t1:.6g} s since 1970 (interface 1: if_tsoffset {2**40} s, "
            f"100000000000000000000 ticks/s)") in notes[1]
    assert notes[2] == "[]}"


def test_tlog_text_runs_end_at_frames_written_natively(tmp_path: Path, cli: Cli) -> None:
    """Console text one byte an entry, a frame, more text, frames: two separate tlog-text problems, the
    second one not joined to the first across the frame the walker wrote."""
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.native.walk import NativeWalk

    mav = mav2()
    entries = [b"a", b"b", heartbeat(mav), b"c", b"d", b"e", heartbeat(mav), heartbeat(mav)]
    t0 = 1_746_714_528_149_261
    path = tmp_path / "console.tlog"
    path.write_bytes(tlog_spaced(entries, t0, 20))
    result = same(cli, path)
    assert result.out.count("\n") == 3
    lines = result.err.splitlines()
    assert len(lines) == 2 and "tlog entries 1-2: 2 bytes" in lines[0] and "tlog entries 4-6: 3 bytes" in lines[1]
    with NativeWalk(path, load_dialect(), set(), set()) as walk:
        for _ in walk.batches():
            pass
        assert walk.stats()["frames_native"] == 3


def test_frames_released_at_once_are_written_in_chunks(tmp_path: Path, dialect: Dialect) -> None:
    """2,000 HEARTBEATs (pymavlink) in one TCP stream, sent after its SYN as 2,000 segments last first:
    reassembly holds them all until the first segment comes, then releases 2,000 frames from one record.
    They were put as one chunk of 2,000 lines (100,000 segments out of order held 400 MB of lines); now
    no write holds more than LineSink.LINES lines, and the output is the pure path's, line for line."""
    from mavscope.native.walk import LineSink

    mav = mav2()
    frames = []
    for _ in range(2000):
        frames.append(heartbeat(mav))
        mav.seq = (mav.seq + 1) % 256
    offsets = [sum(len(f) for f in frames[:k]) for k in range(len(frames))]

    def segment(seq: int, payload: bytes, flags: int = 0x18) -> bytes:
        return nh.link("ethernet", nh.ipv4(b"\x0a\0\0\x02", b"\x0a\0\0\x01", 6,
                                           nh.tcp(40000, 5760, seq, payload, flags)), False)

    records = [(1_700_000_000, 0, segment(999, b"", 0x02))]  # the SYN: the stream starts at 1000
    records += [(1_700_000_000, 1 + k, segment(1000 + offsets[k], frames[k])) for k in reversed(range(2000))]
    path = tmp_path / "reversed.pcap"
    path.write_bytes(nh.pcap(records, nh.LINKTYPES["ethernet"]))
    writes: list[int] = []
    real_put = LineSink._put

    def put(self: LineSink, lines: list[bytes]) -> None:
        writes.append(len(lines))
        real_put(self, lines)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(LineSink, "_put", put)
        out, err, _ = native_output(path, dialect)
    expected, expected_err = pure_output(path, dialect)
    assert out == expected and err == expected_err
    assert out.count(b'"HEARTBEAT"') == 2000 and sum(writes) == 2000
    assert max(writes) <= LineSink.LINES


def test_the_writer_holds_at_most_queued_chunks_for_a_slow_reader() -> None:
    """An output that takes nothing until released: 500 chunks put by another thread wait at most
    _Writer.QUEUED at once (the producer blocks), and all of them are written, in order, once it reads."""
    import io
    import threading
    import time

    from mavscope.native.walk import _Writer

    gate = threading.Event()

    class Slow(io.BytesIO):
        def write(self, b: bytes) -> int:  # type: ignore[override]
            gate.wait()
            return super().write(b)

    out = Slow()
    writer = _Writer(out)
    producer = threading.Thread(target=lambda: [writer.put(b"%03d," % k) for k in range(500)])
    producer.start()
    deadline = time.monotonic() + 30
    while writer.queue.qsize() < _Writer.QUEUED and time.monotonic() < deadline:
        time.sleep(0.01)
    # full (it was never full: unbounded), and the producer blocked with 500 - QUEUED - 1 chunks to go
    assert writer.queue.full() and writer.queue.qsize() == _Writer.QUEUED and producer.is_alive()
    gate.set()
    producer.join()
    writer.close()
    assert out.getvalue() == b"".join(b"%03d," % k for k in range(500))
