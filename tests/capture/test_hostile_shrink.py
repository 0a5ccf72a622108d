"""A capture that shrinks while it is read (log rotation, a restarted writer) ends with a note, never SIGBUS.

Memory-mapped reading killed the process (exit 135) when the file was truncated under the mapping; the
readers and the TUI's index now read with pread. The scenarios run in a child process so that, should
the fault come back, the test fails instead of killing the test run. Window boundaries are also
crossed on purpose (a tiny window) and must not change a single record.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from mavscope.capture.base import LINKTYPE_ETHERNET, LINKTYPE_RAW, Record
from mavscope.capture.detect import open_capture
from mavscope.capture.synth import udp_packet
from mavscope.capture.writer import PcapngWriter
from tests.support.builders import tlog, write_pcap
from tests.support.pmav import heartbeat, mav2, statustext

ROOT = Path(__file__).resolve().parents[2]
T0 = 1_700_000_000.0
COUNT = 3000


def _frames() -> list[bytes]:
    mav = mav2()
    return [heartbeat(mav) if i % 3 else statustext(mav, f"message {i}" * (1 + i % 4)) for i in range(COUNT)]


def make_capture(path: Path, kind: str) -> None:
    """A capture of COUNT MAVLink frames of `kind` (pcap, pcapng, tlog, raw), a few hundred KB."""
    frames = _frames()
    if kind == "pcap":
        write_pcap(path, [(T0 + i / 100, udp_packet("10.0.0.1", 14550, "10.0.0.2", 14540, f))
                          for i, f in enumerate(frames)])
    elif kind == "pcapng":
        with PcapngWriter(path, LINKTYPE_ETHERNET, nanosecond=True) as w:
            for i, f in enumerate(frames):
                pkt = udp_packet("10.0.0.1", 14550, "10.0.0.2", 14540, f)
                w.write(T0 + i / 100, pkt[14:] if i % 2 else pkt, linktype=LINKTYPE_RAW if i % 2 else None)
    elif kind == "tlog":
        path.write_bytes(tlog([(T0 + i / 100, f) for i, f in enumerate(frames)]))
    else:
        path.write_bytes(b"\x00garbage" + b"".join(frames) * 4)


KINDS = ["pcap", "pcapng", "tlog", "raw"]


def shrink_while_reading(path: str, window: int, after: int) -> None:
    """Read `after` records, truncate the file to a third, read the rest: the records up to the cut, then a
    note saying the file shrank (unless the reader had read every byte before the cut)."""
    with open_capture(path) as reader:
        full = list(reader)
    content = Path(path).read_bytes()
    with open_capture(path) as reader:
        full_size = reader.size
        reader.window = window
        records = [next(reader) for _ in range(min(after, len(full) // 4))]
        os.truncate(path, full_size // 3)
        records += list(reader)
        assert reader.position == reader.size
        assert reader.opened_size == full_size
    shrank = [n for r in records for n in r.notes if n.code == "record-truncated" and "shrank" in n.message]
    if records == full:  # every byte had been read before the cut
        assert not shrank
    else:
        assert reader.size < full_size and len(shrank) == 1 and shrank[0] in records[-1].notes, records[-1]
        before = [r for r in full if r.offset + len(r.data) <= reader.size]  # wholly before the cut
        assert before and records[:len(before)] == before
        assert all(r.data == content[r.offset:r.offset + len(r.data)] for r in records)  # nothing made up
        assert sum(len(r.data) for r in records) > full_size // 5  # the bytes before the cut were read
    print("OK", len(records), len(full))


def _child(code: str) -> None:
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"exit status {proc.returncode} (-7/135: SIGBUS)\n{proc.stdout}\n{proc.stderr}"
    assert "OK" in proc.stdout


@pytest.mark.parametrize(("window", "after"), [(1 << 20, 0), (1 << 20, 1), (4096, 1), (4096, 500)])
@pytest.mark.parametrize("kind", KINDS)
def test_a_capture_that_shrinks_while_read_ends_with_a_note(tmp_path: Path, kind: str, window: int,
                                                            after: int) -> None:
    path = tmp_path / f"shrinking.{kind}"
    make_capture(path, kind)
    with open_capture(path) as reader:
        assert reader.kind == kind
    _child("from tests.capture.test_hostile_shrink import shrink_while_reading as s; "
           f"s({str(path)!r}, {window}, {after})")


def index_after_shrink(path: str) -> None:
    """Index a capture, truncate it, then ask for frames before and after the cut: no fault."""
    from mavscope.browse.index import FrameIndex
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.pipeline.dissect import Dissector

    dialect = load_dialect()
    index = FrameIndex(dialect, path)
    file_bytes = getattr(index, "_bytes", None)
    if file_bytes is not None:
        file_bytes.window = 4096  # the rows checked below are not in its window
    with open_capture(path) as reader:
        index.build(Dissector(dialect).run(reader))
    n = len(index)
    assert n == COUNT
    size = os.path.getsize(path)
    os.truncate(path, size // 2)
    assert index.frame(0).msgid in (0, 253)
    gone = 0
    for i in (n // 4, 3 * n // 4):
        try:
            index.detail(i)
            index.raw(i)
        except IndexError as exc:  # the frame's bytes are gone: reported like a dropped row
            assert "shrank" in str(exc)
            gone += 1
    assert gone == 1
    assert len(list(index.frames())) < n
    index.close()
    print("OK")


def test_the_index_survives_a_capture_that_shrinks(tmp_path: Path) -> None:
    path = tmp_path / "indexed.pcap"
    make_capture(path, "pcap")
    _child(f"from tests.capture.test_hostile_shrink import index_after_shrink; index_after_shrink({str(path)!r})")


def _read(path: Path, window: int | None = None) -> list[Record]:
    with open_capture(path) as reader:
        if window is not None:
            reader.window = window
        return list(reader)


def _damage(content: bytes, seed: int) -> bytes:
    """Bit flips, an inserted run of garbage and absurd lengths, at places chosen by `seed`."""
    import random

    rng = random.Random(seed)
    b = bytearray(content)
    for _ in range(8):
        b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
    at = rng.randrange(len(b))
    b[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 700)))
    for _ in range(2):
        at = rng.randrange(len(b) - 4)
        b[at:at + 4] = struct.pack("<I", rng.choice([0x7FFFFFF0, 0x00FFFFF0, 70000]))
    return bytes(b[: len(b) - rng.randrange(300)])


@pytest.mark.parametrize("kind", KINDS)
def test_records_do_not_depend_on_the_read_window(tmp_path: Path, kind: str) -> None:
    """Records, damage notes and resynchronisation are the same whatever the window (records and blocks
    crossing window boundaries; resynchronisation scanning across several windows)."""
    path = tmp_path / f"clean.{kind}"
    make_capture(path, kind)
    clean = path.read_bytes()
    for seed in range(6):
        content = clean if seed == 0 else _damage(clean, seed)
        path.write_bytes(content)
        expected = _read(path)
        assert expected and sum(len(r.data) for r in expected) > len(content) // 2
        for window in (64, 333, 4096):
            assert _read(path, window) == expected, (seed, window)
