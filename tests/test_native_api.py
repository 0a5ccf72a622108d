"""The native engine's Python side: the layout table, the batch walker's segments and shared state,
Dissector.feed/finish/passed, the writer thread, the engine switch."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import pytest

from mavscope.capture.base import Record
from mavscope.capture.detect import open_capture
from mavscope.cli import Env, main
from mavscope.dissect import Dissector
from mavscope.mavlink.dialect import Dialect
from tests import native_helpers as nh
from tests.conftest import CAPTURES

native_mod = pytest.importorskip("mavscope._native", reason="the native extension is not built")

from mavscope import native  # noqa: E402 - after the skip


def test_table_describes_every_message_from_the_dialect(dialect: Dialect) -> None:
    blob = native.build_table(dialect)
    assert native_mod.Table(blob).count() == len(dialect.messages)
    # offsets in the padded payload are the FieldDefs' wire offsets (pymavlink's layout)
    pos = 12
    by_id = {}
    while pos < len(blob):
        msgid, _, length, _, python_only, nfields, name_len = struct.unpack_from("<IBBBBHH", blob, pos)
        pos += 12 + name_len
        offsets = []
        for _ in range(nfields):
            _, _, offset, key_len = struct.unpack_from("<BBBB", blob, pos)
            offsets.append(offset)
            pos += 4 + key_len
        by_id[msgid] = (python_only, offsets)
    for md in dialect.messages.values():
        python_only, offsets = by_id[md.id]
        assert not python_only, md.name
        assert offsets == [f.offset for f in md.fields], md.name


def test_a_malformed_table_is_refused() -> None:
    with pytest.raises(ValueError):
        native_mod.Table(b"MSNT\x01\x00\x00\x00\x05\x00\x00\x00")


def test_feed_and_finish_give_what_run_gives(dialect: Dialect) -> None:
    for name in ("px4_sitl_tcp.pcap", "serial_dump.raw", "damaged.pcap", "px4_sitl_udp.pcap"):
        with open_capture(CAPTURES / name) as r:
            whole = list(Dissector(dialect).run(r))
        d = Dissector(dialect)
        fed = []
        with open_capture(CAPTURES / name) as r:
            for rec in r:
                fed.extend(d.feed(rec))
        fed.extend(d.finish())
        assert fed == whole, name


def test_segments_keep_capture_order_and_hand_back_records(dialect: Dialect) -> None:
    endpoints: set[str] = set()
    senders: set[tuple[int, int]] = set()
    with native.NativeWalk(CAPTURES / "damaged.pcap", dialect, endpoints, senders) as walk:
        segs = list(walk.segments(limit=1))
        stats = walk.stats()
    records = [s for s in segs if isinstance(s, Record)]
    assert [r.number for r in records] == sorted(r.number for r in records)
    assert len(records) == stats["records_handed_back"] > 0
    with open_capture(CAPTURES / "damaged.pcap") as r:
        originals = {rec.number: rec for rec in r}
    for rec in records:
        assert rec == originals[rec.number]  # the very Record the Python reader makes, notes included


def test_shared_state_is_the_python_sets(dialect: Dialect) -> None:
    endpoints: set[str] = set()
    senders: set[tuple[int, int]] = set()
    with native.NativeWalk(CAPTURES / "signed_udp.pcap", dialect, endpoints, senders) as walk:
        list(walk.segments(lambda: True))
    assert endpoints == {"127.0.0.1:14580", "127.0.0.1:14550"}
    assert senders == {(1, 1), (255, 190)}
    # with signed frames handed back, Python's security stage (not the walker) fills the set
    senders2: set[tuple[int, int]] = set()
    with native.NativeWalk(CAPTURES / "signed_udp.pcap", dialect, set(), senders2) as walk:
        segs = list(walk.segments(lambda: False))
    assert senders2 == set()
    assert all(isinstance(s, Record) for s in segs)


def test_a_sender_known_to_sign_makes_its_unsigned_frames_python_s(dialect: Dialect) -> None:
    with native.NativeWalk(CAPTURES / "px4_sitl_udp.pcap", dialect, set(), {(1, 1)}) as walk:
        segs = list(walk.segments())
    handed = [s for s in segs if isinstance(s, Record)]
    assert len(handed) > 500  # every datagram with a frame of 1/1 goes to Python for its note


def test_tcp_flushed_at_the_end_after_native_records(tmp_path: Path, dialect: Dialect) -> None:
    """Frames completed at the end of the capture belong to its last record, even when the walker wrote
    that one (Dissector.passed), and are numbered after what the general scanner counted in it."""
    md = dialect.by_name["HEARTBEAT"]
    hb = nh.frame_v2(md, md.id, bytes(9), 0, 1, 1)
    cut = hb[:7]  # a frame the TCP stream never completes
    v1 = nh.frame_v1(md, bytes(md.base_length), 5, 1, 1)
    lo = b"\x7f\0\0\1"
    recs = [
        (1_700_000_000, 0, nh.link("ethernet", nh.ipv4(lo, lo, 6, nh.tcp(5760, 40000, 1, hb + cut)), False)),
        (1_700_000_001, 0, nh.link("ethernet", nh.ipv4(lo, lo, 17, nh.udp(14550, 14550, v1 + v1)), False)),
    ]
    path = tmp_path / "mixed.pcap"
    path.write_bytes(nh.pcap(recs, 1))
    pure = nh.pure_output(path, dialect)
    out, err, stats = nh.native_output(path, dialect)
    assert stats["frames_native"] == 2
    assert (out, err) == pure
    assert b'"frame":2,"index":3' in out  # the cut frame, flushed at the end


def test_writer_thread_passes_on_a_closed_pipe(dialect: Dialect) -> None:
    class Closed(io.RawIOBase):
        def writable(self) -> bool:
            return True

        def write(self, b: object) -> int:
            raise BrokenPipeError(32, "Broken pipe")

    from mavscope.security.stage import SecurityStage

    with pytest.raises(BrokenPipeError):
        native.write_jsonl(CAPTURES / "px4_sitl_udp.pcap", dialect, SecurityStage(), Closed(), lambda a: None)


def test_threaded_and_unthreaded_output_agree(dialect: Dialect) -> None:
    a = nh.native_output(CAPTURES / "px4_sitl_udp.pcap", dialect, threaded=True)
    b = nh.native_output(CAPTURES / "px4_sitl_udp.pcap", dialect, threaded=False)
    assert a[:2] == b[:2]


def test_version_names_the_engine(capsys: pytest.CaptureFixture[str]) -> None:
    for environ, name in (({}, "native"), ({"MAVSCOPE_PURE": "1"}, "pure-python")):
        with pytest.raises(SystemExit):
            main(["--version"], Env(environ=environ))
        assert capsys.readouterr().out.strip().endswith(f"(engine: {name})")


def test_without_the_extension_the_engine_is_pure(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(native, "_native", None)
    assert native.engine({}) == "pure-python"


def test_recycled_buffers_give_the_same_text(dialect: Dialect) -> None:
    """Batches written into a pool of bytearrays (as write_jsonl does): a batch without text keeps its
    buffer for the next one, so a pool of two never runs dry over 105 handed-back records."""
    import queue

    def text(buffers: object) -> bytes:
        out = []
        with native.NativeWalk(CAPTURES / "securemav_udp.pcap", dialect, set(), set()) as walk:
            for seg in walk.segments(limit=1, buffers=buffers):  # type: ignore[arg-type]
                if not isinstance(seg, Record):
                    out.append(bytes(seg))
                    if isinstance(seg, bytearray):
                        pool.put(seg)
        return b"".join(out)

    pool: queue.Queue[bytearray] = queue.Queue()
    for _ in range(2):
        pool.put(bytearray())
    assert text(lambda: pool.get(timeout=5)) == text(None)
    assert pool.qsize() >= 1  # the last unused buffer ends with the walk
