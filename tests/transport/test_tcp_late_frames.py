"""Frames a TCP hole held back come out after frames of later records, and every consumer takes them so.

A frame is the record's that completed it (issue 35, item 10): the HEARTBEATs that waited for a hole the
capture missed are dated by their own segments' records when the hole is given up, records later, so frames
of record 14 come out after those of records 15, 17 and 19 (UDP datagrams of another link read meanwhile).
The class: every consumer that took frames to come in record order (the TUI index's binary search for a
record, `read -w`, `read -Y 'frame.number == N'`, the engines' agreement). Also here: a hole found behind a
younger one is given up on time (the heap of `since`), and the hot path's shortcuts (an ACK that passes no
delivered byte, a frame in one piece) give what the long way gives.

Every capture is built by tests/support/tcpflows.py; the expected order, records and times come from that
construction and the rule (a hole is given up at the first TCP segment more than HOLE_TIMEOUT, 2 s, after
the bytes beyond it came; its frames then come out before that segment's own), never from mavscope.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from scapy.utils import rdpcap

from mavscope.browse.index import FrameIndex
from mavscope.capture.detect import open_capture
from mavscope.endpoint import Endpoint
from mavscope.mavlink.framing import Framer, StreamFramer
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.transport.tcp import HOLE_TIMEOUT, TCP_ACK, TcpReassembler
from tests.support import tcpflows as tf
from tests.support.flows import Sender, heartbeat
from tests.support.tui import ready, run

N = 12  # HEARTBEATs of 1/1 over TCP at t = 0..11 (the one of t=5 not captured), of 2/1 over UDP at t + 0.5


def interleaved(tmp: Path) -> tuple[tf.Capture, Path]:
    other = Sender(2, 1)
    cap = tf.build(tf.one_per_segment(tf.heartbeats(N)), missed={5}, acks=False,
                   udp=[other.pack(heartbeat()) for _ in range(N)])
    return cap, cap.write(tmp / "interleaved.pcap")


def expected_order(cap: tf.Capture) -> list[int]:
    """The records of the frames in the order they are completed, by the rule: the TCP HEARTBEATs of t=6, 7
    and 8 wait for the hole of t=5 until the first record more than 2 s after t=6 (any record ticks the
    reassembler's clock: the datagram of t=8.5), and come out there after its own frame, before t=9's; each
    datagram's frame comes out at its record, half a second after its segment."""
    assert HOLE_TIMEOUT == 2.0
    order: list[int] = []
    for i in range(N):
        if i == 9:
            order += [cap.record_of[k] for k in (6, 7, 8, 9)]
        elif i not in (5, 6, 7, 8):
            order.append(cap.record_of[i])
        order.append(cap.udp_of[i])
    return order


def first_rows(order: list[int]) -> dict[int, int]:
    rows: dict[int, int] = {}
    for row, record in enumerate(order):
        rows.setdefault(record, row)
    return rows


def test_frames_held_by_a_hole_come_after_later_records(tmp_path: Path, dialect) -> None:  # type: ignore[no-untyped-def]
    cap, path = interleaved(tmp_path)
    with open_capture(path) as reader:
        frames = [f for f in Dissector(dialect).run(reader) if type(f) is not Anomaly]
    assert [f.record for f in frames] == expected_order(cap)
    late = frames[expected_order(cap).index(cap.record_of[6])]
    assert (late.sysid, late.seq, late.time) == (1, 6, tf.T0 + 6)
    assert cap.record_of[6] < cap.udp_of[8]  # out of record order, as built


def _index_by(path: Path, dialect, how: str) -> FrameIndex:  # type: ignore[no-untyped-def]
    index = FrameIndex(dialect, path)
    if how == "native":
        from mavscope.native import core
        from mavscope.native import index as native
        from mavscope.security.stage import SecurityStage
        from tests.native.engines import material

        if not core.available({}):
            pytest.skip("the native extension is not built")
        native.native_build(index, os.fspath(path), dialect, SecurityStage(material("none")))
    else:
        with open_capture(path) as reader:
            index.build(Dissector(dialect).run(reader))
    return index


@pytest.mark.parametrize("how", ["pure", "native"])
def test_the_tui_index_finds_every_record_out_of_order(tmp_path: Path, dialect, how: str) -> None:  # type: ignore[no-untyped-def]
    """find_record (the TUI's go-to from the expert, events and objects screens) gives each record's first
    row in the order above, the late ones too; a record with no frame (the handshake, the segment missed's
    absence, a record past the end) gives none. Both index builds alike."""
    cap, path = interleaved(tmp_path)
    order = expected_order(cap)
    index = _index_by(path, dialect, how)
    assert [index.row(i).record for i in range(len(index))] == order
    for record, row in first_rows(order).items():
        assert index.find_record(record) == row, record
    for record in (1, 2, 3, max(order) + 1):
        assert index.find_record(record) is None
    index.limit = len(index)  # a bounded (live) index dropping its oldest rows keeps finding the rest
    index.trim(4)
    for record, row in first_rows(order).items():
        assert index.find_record(record) == (row if row >= 4 else None), record
    index.close()


def test_an_index_chunk_out_of_order_is_found_too(tmp_path: Path, dialect) -> None:  # type: ignore[no-untyped-def]
    """`extend` (a native chunk) after a row of record 8: its rows of records 10, 5, 11 and 5 hold late rows
    of record 5 (the 2nd and 4th); record 5's first row is the chunk's 2nd, 10's its 1st."""
    from mavscope.native.index import Chunk

    index = FrameIndex(dialect)
    one = tf.build(tf.one_per_segment(tf.heartbeats(1)), acks=False).write(tmp_path / "one.pcap")
    with open_capture(one) as reader:
        (frame,) = [f for f in Dissector(dialect).run(reader) if type(f) is not Anomaly]
    index.add(frame._replace(record=8))
    cols = {"record": ("i8", [10, 5, 11, 5]), "index": ("i4", [1] * 4), "time": ("f8", [1.0] * 4),
            "time_ok": ("u1", [1] * 4), "transport": ("u1", [0] * 4), "src": ("i4", [0] * 4), "dst": ("i4", [0] * 4),
            "incompat_flags": ("u1", [0] * 4), "seq": ("u1", [0] * 4), "sysid": ("u1", [1] * 4),
            "compid": ("u1", [1] * 4), "msgid": ("u4", [0] * 4), "offset": ("i8", [-1] * 4), "size": ("u2", [21] * 4)}
    chunk = Chunk(4, [np.array(v, t).tobytes() for t, v in cols.values()], tuple(cols))
    index.extend(chunk, None, ("udp",))
    assert [index.row(i).record for i in range(5)] == [8, 10, 5, 11, 5]
    assert [index.find_record(r) for r in (8, 10, 5, 11, 6)] == [0, 1, 2, 3, None]


def test_the_tui_goes_to_a_late_frame(tmp_path: Path) -> None:
    """The app's go-to (as Enter on an expert finding does) selects the row of the late record, and of the
    datagram before it."""
    from mavscope.tui.app import create_app
    from tests.support.tui import SIZE

    cap, path = interleaved(tmp_path)
    rows = first_rows(expected_order(cap))

    async def scenario() -> None:
        app = create_app(path)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            for record in (cap.record_of[6], cap.udp_of[8], cap.record_of[9]):
                app.goto_record(record)
                await pilot.pause()
                assert app.packet_list.cursor_row == rows[record]
                assert app.index.row(app.packet_list.cursor_row).record == record

    run(scenario())


def test_read_w_and_frame_number_filters_take_late_frames(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """`read -Y 'frame.number == N'` shows the frame of record N, late or not; `-w` writes its record (the
    segment of t=6, by its sequence number and time); the frames of 1/1 all (given out of order) write the
    TCP records that carried them in capture order: a capture that reads back the same."""
    cap, path = interleaved(tmp_path)
    segs = tf.one_per_segment(tf.heartbeats(N))
    for record, (sysid, seq, t) in ((cap.record_of[6], (1, 6, 6.0)), (cap.udp_of[8], (2, 8, 8.5))):
        (got,) = cli.jsonl(path, "-Y", f"frame.number == {record}")
        assert (got["frame"], got["sysid"], got["seq"], got["time"]) == (record, sysid, seq, tf.T0 + t)
    status, _, err = cli("read", path, "-Y", f"frame.number == {cap.record_of[6]}", "-w", tmp_path / "six.pcap")
    assert status == 0, err
    assert [(int(p["TCP"].seq), float(p.time)) for p in rdpcap(str(tmp_path / "six.pcap"))] == \
        [(segs[6].seq, tf.T0 + 6)]
    status, _, err = cli("read", path, "-Y", "mavlink.sysid == 1", "-w", tmp_path / "tcp.pcap")
    assert status == 0, err
    assert [(int(p["TCP"].seq), float(p.time)) for p in rdpcap(str(tmp_path / "tcp.pcap"))] == \
        [(s.seq, tf.T0 + s.t) for i, s in enumerate(segs) if i != 5]


@pytest.mark.parametrize("command", [("read",), ("read", "-T", "jsonl"), ("stats",), ("stats", "--json")],
                         ids=["read", "jsonl", "stats", "stats-json"])
def test_both_engines_agree_on_late_frames(cli, tmp_path: Path, command: tuple[str, ...]) -> None:  # type: ignore[no-untyped-def]
    """Late TCP frames among native UDP records: the same stdout, stderr and exit status on both engines."""
    _, path = interleaved(tmp_path)
    native = cli(command[0], path, *command[1:], environ={})
    assert native == cli(command[0], path, *command[1:], environ={"MAVSCOPE_PURE": "1"})
    assert native.status == 0 and native.out


# --- the reassembler: a hole found behind a younger one; the ACK shortcut ----------------------------------


A, B, C = Endpoint("10.0.0.1", 1), Endpoint("10.0.0.2", 2), Endpoint("10.0.0.3", 3)


def test_a_hole_found_behind_a_younger_one_is_given_up_on_time() -> None:
    """Direction A->B misses bytes 10-19 and 30-39: the bytes beyond the second came at t=0.1. B->C misses
    bytes 10-19 at t=1.0. At t=1.5 the retransmission of A's 10-19 fills the first hole, so A now waits on
    its second, whose bytes beyond came at t=0.1, behind B's younger hole (t=1.0). By the rule A's is given
    up at the first segment more than 2 s after t=0.1 (t=2.2, not t=2.05), B's more than 2 s after t=1.0
    (not at t=2.2). A's bytes 40-49 are then readable from record 6 (t=1.5): a receiver reads them after
    bytes 10-19, which came there; B's 20-29 from their own record 5 (nothing before them came later)."""
    r = TcpReassembler()
    assert [p.data for p in r.segment(A, B, 0, TCP_ACK, b"a" * 10, 1, 0, None, 0.0)] == [b"a" * 10]
    assert r.segment(A, B, 20, TCP_ACK, b"c" * 10, 2, 0, None, 0.0) == []
    assert r.segment(A, B, 40, TCP_ACK, b"e" * 10, 3, 0, None, 0.1) == []
    r.segment(B, C, 0, TCP_ACK, b"p" * 10, 4, 0, None, 1.0)
    assert r.segment(B, C, 20, TCP_ACK, b"r" * 10, 5, 0, None, 1.0) == []
    filled = r.segment(A, B, 10, TCP_ACK, b"b" * 10, 6, 0, None, 1.5)
    assert [(p.data, p.record) for p in filled] == [(b"b" * 10, 6), (b"c" * 10, 2)]
    assert [p.src for p in r.segment(C, A, 0, TCP_ACK, b"x", 7, 0, None, 2.05)] == [C]  # a third stream: the clock
    given = r.segment(C, A, 1, TCP_ACK, b"x", 8, 0, None, 2.2)
    (late,) = [p for p in given if p.src == A]
    assert (late.data, late.record, late.ready) == (b"e" * 10, 3, (6, 1.5))
    assert [n.code for n in late.notes] == ["tcp-gap"] and "30-39" in late.notes[0].message
    assert not [p for p in given if p.src == B]  # B's waited 1.2 s
    (b,) = [p for p in r.segment(C, A, 2, TCP_ACK, b"x", 9, 0, None, 3.05) if p.src == B]
    assert (b.data, b.ready) == (b"r" * 10, (5, 1.0))


def test_an_ack_past_a_hole_across_the_sequence_wrap_is_taken() -> None:
    """The ACK shortcut (an ACK that passes no delivered byte is not looked at) across 2**32: bytes delivered
    up to 2**32 + 5, a segment at +15 (10 bytes missing): the peer's ACK of sequence number 25 (2**32 + 25)
    passes them, so the hole is given up at once and the bytes beyond delivered; an ACK of 5 (what was
    delivered), of 2**32 - 100 (behind) and a later one of 25 again change nothing."""
    r = TcpReassembler()
    start = (1 << 32) - 10
    assert [p.data for p in r.segment(A, B, start, TCP_ACK, b"a" * 15, 1, 0, None, 0.0)] == [b"a" * 15]
    assert r.segment(A, B, 15, TCP_ACK, b"c" * 10, 2, 0, None, 0.1) == []
    assert r.segment(B, A, 0, TCP_ACK, b"", 3, 0, 5, 0.2) == []
    assert r.segment(B, A, 0, TCP_ACK, b"", 4, 0, (1 << 32) - 100, 0.3) == []
    got = r.segment(B, A, 0, TCP_ACK, b"", 5, 0, 25, 0.4)
    assert [(p.data, p.record, [n.code for n in p.notes]) for p in got] == [(b"c" * 10, 2, ["tcp-gap"])]
    assert got[0].notes[0].message.startswith("10 bytes missing")
    assert r.segment(B, A, 0, TCP_ACK, b"", 6, 0, 25, 0.5) == []


def test_the_stream_framer_dates_a_frame_by_the_piece_of_its_last_byte(dialect) -> None:  # type: ignore[no-untyped-def]
    """Three HEARTBEATs (21 bytes each) fed in pieces of records 4 (bytes 0-29), 5 (30-41) and 6 (42-62), each
    readable at (record, time) (7, 1.0), (8, 2.0), (9, 3.0): the first frame lies in piece 4 (span (4,),
    done (7, 1.0)); the second, bytes 21-41, in pieces 4 and 5 ((4, 5), (8, 2.0)); the third, 42-62, in 6."""
    hbs = tf.heartbeats(3)
    data = b"".join(hbs)
    sf = StreamFramer(Framer(dialect.messages), "k")
    sf.trusted = True
    sf.feed(data[:30], 4, 100, (), (7, 1.0))
    sf.feed(data[30:42], 5, 200, (), (8, 2.0))
    sf.feed(data[42:], 6, 300, (), (9, 3.0))
    found, _ = sf.take(False)
    assert [(bytes(b[p:p + s]), off, span, done) for b, p, s, _, _, off, span, _, done in found] == [
        (hbs[0], 100, (4,), (7, 1.0)), (hbs[1], 121, (4, 5), (8, 2.0)), (hbs[2], 300, (6,), (9, 3.0))]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_hole_waits_past_the_timeout_among_many(seed: int) -> None:
    """Random segments (and ACKs) among 6 endpoints, the clock moving by up to 0.5 s now and then: after each
    segment no hole has waited more than HOLE_TIMEOUT since the bytes beyond it came (the rule, checked on
    the reassembler's state), and the heap of holes stays within twice the holes waiting (stale entries go)."""
    import random

    rng = random.Random(seed)
    eps = [Endpoint(f"10.0.0.{i}", 1) for i in range(6)]
    r, t = TcpReassembler(), 0.0
    for n in range(20_000):
        src, dst = rng.sample(eps, 2)
        if rng.random() < 0.01:
            t += rng.random() * 0.5
        ack = rng.randrange(4000) if rng.random() < 0.3 else None
        r.segment(src, dst, rng.randrange(4000), TCP_ACK, b"x" * rng.randrange(1, 30), n + 1, 0, ack, t)
        assert all(r.clock - d.since <= HOLE_TIMEOUT for d in r._holes.values()), n
        assert len(r._due) <= 2 * len(r._holes) + 65
