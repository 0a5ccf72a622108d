"""The native engine's Python side: the layout table, the batch walker's batches and shared state,
Dissector.feed/finish/passed, the writer thread, the engine switch."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import pytest

from mavscope.capture.base import LINKTYPE_MAVLINK_TLOG
from mavscope.capture.detect import open_capture
from mavscope.capture.reader import make_record
from mavscope.cli import Env, main
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.native.table_blob import build_table
from mavscope.pipeline.dissect import Dissector
from tests.conftest import CAPTURES
from tests.native import build as nh
from tests.native.engines import native_output, pure_output
from tests.support.pmav import heartbeat, mav2

native_mod = pytest.importorskip("mavscope._native", reason="the native extension is not built")

from mavscope.native import walk as native  # noqa: E402 - after the skip


def test_table_describes_every_message_from_the_dialect(dialect: Dialect) -> None:
    blob = build_table(dialect)
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


def test_passed_ends_a_run_of_text_entries_as_feed_would(dialect: Dialect) -> None:
    """Two text entries, then a HEARTBEAT entry: fed, it reports the run before its frame; told with
    passed() (the walker wrote it), the run comes back from passed(), and a later text entry starts a run
    of its own."""
    t = 1_700_000_000.0
    text = [make_record(i, t, LINKTYPE_MAVLINK_TLOG, bytes([c]), 8 + 9 * (i - 1), 1) for i, c in ((1, 65), (2, 66))]
    frame = make_record(3, t + 1, LINKTYPE_MAVLINK_TLOG, heartbeat(mav2()), 26, 21)
    later = make_record(4, t + 2, LINKTYPE_MAVLINK_TLOG, b"C", 55, 1)
    fed = Dissector(dialect)
    items = [item for rec in (*text, frame, later) for item in fed.feed(rec)] + list(fed.finish())
    told = Dissector(dialect)
    for rec in text:
        assert list(told.feed(rec)) == []  # held for the next record
    held = told.passed(3, t + 1)
    assert held == items[:1] and held[0].record == 1 and "'AB'" in held[0].notes[0].message
    assert told.passed(3, t + 1) == []
    rest = list(told.feed(later)) + list(told.finish())
    assert rest == items[2:] and rest[0].record == 4  # the frame (items[1]) was the walker's


def walk_all(path: Path, dialect: Dialect, endpoints: set[Endpoint] | None = None,
             senders: set[tuple[int, int]] | None = None, nokey: bool = False,
             limit: int = 1 << 20) -> tuple[list[native.Batch], dict[str, int]]:
    with native.NativeWalk(path, dialect, set() if endpoints is None else endpoints,
                           set() if senders is None else senders) as walk:
        batches = list(walk.batches(lambda: nokey, limit=limit))
        return batches, walk.stats()


def test_batches_keep_capture_order_and_hand_back_records(dialect: Dialect) -> None:
    batches, stats = walk_all(CAPTURES / "damaged.pcap", dialect, limit=1)
    records = [b.record for b in batches if b.record is not None]
    assert len(records) == stats["records_handed_back"] > 0
    with open_capture(CAPTURES / "damaged.pcap") as r:
        originals = {rec.number: rec for rec in r}
    for rec in records:
        assert rec == originals[rec.number]  # the very Record the Python reader makes, notes included
    # every record is walked natively or handed back, in capture order
    numbers = []
    for b in batches:
        if b.walked is not None:
            numbers.append(b.walked[0])
        if b.record is not None:
            numbers.append(b.record.number)
    assert numbers == sorted(numbers) and numbers[-1] == max(originals)
    assert stats["records_native"] + stats["records_handed_back"] == len(originals)


def test_shared_state_is_the_python_sets(dialect: Dialect) -> None:
    endpoints: set[Endpoint] = set()
    senders: set[tuple[int, int]] = set()
    walk_all(CAPTURES / "signed_udp.pcap", dialect, endpoints, senders, nokey=True)
    # the Endpoints the transport layer makes (equal by address and port), from the packets' headers
    assert endpoints == {Endpoint("127.0.0.1", 14580), Endpoint("127.0.0.1", 14550)}
    assert senders == {(1, 1), (255, 190)}
    # with signed frames handed back, Python's security stage (not the walker) fills the set
    senders2: set[tuple[int, int]] = set()
    batches, _ = walk_all(CAPTURES / "signed_udp.pcap", dialect, set(), senders2, nokey=False)
    assert senders2 == set()
    assert all(b.text is None for b in batches)


def test_a_sender_known_to_sign_has_its_unsigned_frames_written_natively(dialect: Dialect) -> None:
    """The JSON Lines walk writes the unsigned-in-signed-stream note itself (tests/native/test_unsigned_notes.py
    checks the text); the statistics walk still hands those frames to Python."""
    batches, _ = walk_all(CAPTURES / "px4_sitl_udp.pcap", dialect, set(), {(1, 1)})
    unknown, _ = walk_all(CAPTURES / "px4_sitl_udp.pcap", dialect, set(), set())
    handed = [b.record.number for b in batches if b.record is not None]
    assert handed == [b.record.number for b in unknown if b.record is not None]  # no more than for other reasons
    assert b'"code":"unsigned-in-signed-stream"' in b"".join(b.text or b"" for b in batches)


def test_tcp_flushed_at_the_end_after_native_records(tmp_path: Path, dialect: Dialect) -> None:
    """A frame the TCP stream never completes, cut at the end of the capture after a record the walker
    wrote (Dissector.passed), is its own record's (where its 7 bytes are: record 1, after its HEARTBEAT,
    so 1.2), the same on both paths (it was the last record's, dated by the end of the capture)."""
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
    pure = pure_output(path, dialect)
    out, err, stats = native_output(path, dialect)
    assert stats["frames_native"] == 2
    assert (out, err) == pure
    assert b'"frame":1,"index":2,"time":1700000000.0' in out  # the cut frame, flushed at the end


def test_writer_thread_passes_on_a_closed_pipe(dialect: Dialect) -> None:
    class Closed(io.RawIOBase):
        def writable(self) -> bool:
            return True

        def write(self, b: object) -> int:
            raise BrokenPipeError(32, "Broken pipe")

    from mavscope.security.stage import SecurityStage

    class Silent:
        def anomaly(self, item: object) -> None:
            pass

        def frame(self, frame: object) -> None:
            pass

    with pytest.raises(BrokenPipeError):
        native.write_jsonl(CAPTURES / "px4_sitl_udp.pcap", dialect, SecurityStage(), Closed(), Silent())


def test_threaded_and_unthreaded_output_agree(dialect: Dialect) -> None:
    a = native_output(CAPTURES / "px4_sitl_udp.pcap", dialect, threaded=True)
    b = native_output(CAPTURES / "px4_sitl_udp.pcap", dialect, threaded=False)
    assert a[:2] == b[:2]


def test_version_names_the_engine(capsys: pytest.CaptureFixture[str]) -> None:
    for environ, name in (({}, "native"), ({"MAVSCOPE_PURE": "1"}, "pure-python")):
        with pytest.raises(SystemExit):
            main(["--version"], Env(environ=environ))
        assert capsys.readouterr().out.strip().endswith(f"(engine: {name})")


def test_without_the_extension_the_engine_is_pure(monkeypatch: pytest.MonkeyPatch) -> None:
    from mavscope.native import core

    monkeypatch.setattr(core, "_native", None)
    assert core.engine({}) == "pure-python" and not core.available({})


def test_recycled_buffers_give_the_same_text(dialect: Dialect) -> None:
    """Batches written into a pool of bytearrays (as write_jsonl does): a batch without text keeps its
    buffer for the next one, so a pool of two never runs dry over 105 handed-back records."""
    import queue

    def text(buffers: object) -> bytes:
        out = []
        with native.NativeWalk(CAPTURES / "securemav_udp.pcap", dialect, set(), set()) as walk:
            for batch in walk.batches(limit=1, buffers=buffers):  # type: ignore[arg-type]
                if batch.text is not None:
                    out.append(bytes(batch.text))
                    if isinstance(batch.text, bytearray):
                        pool.put(batch.text)
        return b"".join(out)

    pool: queue.Queue[bytearray] = queue.Queue()
    for _ in range(2):
        pool.put(bytearray())
    assert text(lambda: pool.get(timeout=5)) == text(None)
    assert pool.qsize() >= 1  # the last unused buffer ends with the walk
