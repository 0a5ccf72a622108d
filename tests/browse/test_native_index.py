"""The native build of the TUI's index (mavscope.native.index) against the pure build, row for row.

The pure build (`FrameIndex.build` over the Python pipeline: Dissector then security stage, as the TUI
ran it before) is the reference; the native one fills the columns from the C walker's chunks and the
records it hands back through the same pipeline. Every row, its bytes, the rebuilt frame, the anomalies,
the side tables and the memory must be equal: over every bundled capture (with and without a signing
key), every real capture, damaged bytes and Hypothesis-generated captures (tests/native/test_generated.py's
strategy: every link layer, signed and damaged frames, frames the walker hands back), with chunks of a
few frames so that chunk boundaries fall everywhere.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mavscope.browse.index import FrameIndex
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.native import index as native
from mavscope.pipeline.dissect import Dissector
from mavscope.security.stage import SecurityStage
from tests.conftest import CAPTURES
from tests.native.engines import capture_file, material

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

DIALECT = load_dialect()
ALL = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog"))


def pure_index(path: str | Path, dialect: Dialect, keys: str) -> FrameIndex:
    index = FrameIndex(dialect, path)
    with open_capture(path) as reader:
        index.build(SecurityStage(material(keys)).run(Dissector(dialect).run(reader)))
    return index


def native_index(path: str | Path, dialect: Dialect, keys: str) -> FrameIndex:
    index = FrameIndex(dialect, path)
    progress = native.native_build(index, os.fspath(path), dialect, SecurityStage(material(keys)))
    assert progress.done and progress.frames == len(index)
    return index


def assert_same(path: str | Path, dialect: Dialect = DIALECT, keys: str = "none") -> int:
    """Both builds of `path` equal in everything a reader of the index sees; the number of frames."""
    with open_capture(path) as reader:
        kind = reader.kind
    from mavscope.native.core import available

    if not (available() and native.indexes(kind)):
        return -1
    a, b = pure_index(path, dialect, keys), native_index(path, dialect, keys)
    try:
        assert len(a) == len(b)
        for i in range(len(a)):
            assert b.row(i) == a.row(i), i
            assert b.raw(i) == a.raw(i), i
            assert b.frame(i) == a.frame(i), i
        assert b.anomalies == a.anomalies
        assert (b._raw, b._notes, b._spans) == (a._raw, a._notes, a._spans)
        assert (b.first_time, b.memory()) == (a.first_time, a.memory())
        if len(a):
            assert repr(b.detail(len(a) - 1)) == repr(a.detail(len(a) - 1))  # repr: NaN fields equal
        return len(a)
    finally:
        a.close()
        b.close()


@pytest.fixture
def small_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks of a few frames: every boundary between native chunks and handed-back records is crossed."""
    monkeypatch.setattr(native, "FIRST_CHUNK", 2)
    monkeypatch.setattr(native, "CHUNK", 5)


@pytest.mark.parametrize("path", ALL, ids=lambda p: p.name)
@pytest.mark.parametrize("keys", ["none", "key", "leaked"])
def test_bundled_captures(path: Path, keys: str, small_chunks: None) -> None:
    assert assert_same(path, keys=keys) > 0


@pytest.mark.parametrize(("name", "frames"), [("px4_sitl_udp.pcap", 1371), ("serial_dump.raw", 220)])
def test_big_chunks_and_the_walker_takes_most_records(name: str, frames: int) -> None:
    """With the default chunks, on a clean capture the walker takes (nearly) every record; a raw stream's
    clean stretches too (the rows come in bulk, the pieces around damage one by one)."""
    path = CAPTURES / name
    assert assert_same(path) == frames
    index = FrameIndex(DIALECT, path)
    calls = []
    add = index.add
    index.add = lambda f: (calls.append(f), add(f))  # type: ignore[method-assign]
    native.native_build(index, str(path), DIALECT, SecurityStage(material("none")))
    assert len(calls) < len(index) // 10  # the rows came in bulk, not one Frame at a time
    index.close()


def test_real_captures(real_captures: Path, small_chunks: None) -> None:
    checked = 0
    for path in sorted(real_captures.iterdir()):
        if path.suffix in (".pcap", ".pcapng", ".tlog", ".bin", ".raw"):
            checked += assert_same(path) > 0
    assert checked >= 3


@pytest.mark.parametrize("path", ALL, ids=lambda p: p.name)
def test_damaged_bytes(path: Path, small_chunks: None) -> None:
    """Bytes overwritten at a few places of each capture (seeded): whatever the readers make of them."""
    import random

    data = bytearray(path.read_bytes())
    rng = random.Random(path.name)
    for _ in range(8):
        at = rng.randrange(24, len(data))
        data[at] = rng.randrange(256)
    with capture_file(bytes(data)) as name:
        try:
            assert_same(name)
        except Exception as exc:  # a capture too damaged to open: both builds must say so
            with pytest.raises(type(exc)):
                pure_index(name, DIALECT, "none")


from tests.native.test_generated import DAMAGED_FILES, FEWER, capture  # noqa: E402


@FEWER
@given(capture(), st.sampled_from(["none", "key", "leaked"]), st.integers(1, 9))
def test_generated_captures(data: bytes, keys: str, chunk: int) -> None:
    first, every = native.FIRST_CHUNK, native.CHUNK
    native.FIRST_CHUNK, native.CHUNK = chunk, chunk + 3
    try:
        with capture_file(data) as path:
            try:
                pure_index(path, DIALECT, keys).close()
            except Exception as exc:  # noqa: BLE001 - a file no reader opens: the native build says the same
                with pytest.raises(type(exc)):
                    native_index(path, DIALECT, keys)
                return
            assert_same(path, keys=keys)
    finally:
        native.FIRST_CHUNK, native.CHUNK = first, every


@FEWER
@given(*DAMAGED_FILES)
def test_arbitrary_bytes(tail: bytes, head: bytes) -> None:
    with capture_file(head + tail) as path:
        try:
            pure_index(path, DIALECT, "none").close()
        except Exception as exc:  # noqa: BLE001
            with pytest.raises(type(exc)):
                native_index(path, DIALECT, "none")
            return
        assert_same(path)


def test_endpoint_ids_interned_by_python_first(tmp_path: Path, small_chunks: None) -> None:
    """A damaged datagram B -> A comes first (handed back: the index interns B, then A), then clean ones
    A -> B and C -> A (the walker numbers A, B, C): the chunks' ids must be mapped, not taken as they are."""
    from tests.native import build as nh

    hb = DIALECT.by_name["HEARTBEAT"]
    payload = bytes(9)
    a, b, c = bytes([10, 0, 0, 1]), bytes([10, 0, 0, 2]), bytes([10, 0, 0, 3])

    def dgram(src: bytes, dst: bytes, sport: int, dport: int, frame: bytes) -> bytes:
        return nh.link("raw", nh.ipv4(src, dst, 17, nh.udp(sport, dport, frame)), False)

    good = nh.frame_v2(hb, 0, payload, 1, 1, 1)
    bad = good[:-1] + bytes([good[-1] ^ 0xFF])  # bad CRC: handed back
    records = [(1, 0, dgram(b, a, 14550, 14555, bad))]
    records += [(2 + k, 0, dgram(a, b, 14555, 14550, good) if k % 3 else dgram(c, a, 14560, 14555, good))
                for k in range(30)]
    path = tmp_path / "ends.pcap"
    path.write_bytes(nh.pcap(records, 101))  # LINKTYPE_RAW
    calls: list[bool] = []
    extend = FrameIndex.extend

    def spy(self: FrameIndex, chunk: object, ends: object, transports: tuple[str, ...]) -> None:
        calls.append(ends is None)
        extend(self, chunk, ends, transports)

    FrameIndex.extend = spy  # type: ignore[method-assign]
    try:
        assert assert_same(path) == 31
    finally:
        FrameIndex.extend = extend  # type: ignore[method-assign]
    assert calls and not any(calls)  # every chunk went through the id map
