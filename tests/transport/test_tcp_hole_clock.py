"""A TCP hole waits by the capture's clock, not the stream's (issue 35, items 1 and 10; docs/security.md, "Bounds").

A hole in a TCP stream among other traffic used to wait for the next segment of that stream: a stream that
stopped after a lost segment held its last frames until the capture's end (shown after everything else), and
the dissector kept the frame index of every record meanwhile (a frame may be dated by any of them), a table
growing without bound. Now every record, whatever it carries, ticks the reassembler while a hole waits: the
hole is given up at the first record more than HOLE_TIMEOUT (2 s) of capture time after the bytes beyond it
came, and after HOLE_RECORDS records whatever the clock says (a capture whose time stands still); the native
walker hands every record back while a hole waits, so both engines give it up at the same record.

Captures are built by tests/support/tcpflows.py; the expected records and times follow from that construction
(which segment was missed, which record carried what, sent when), worked out by hand in each test.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mavscope.capture.detect import open_capture
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Dissector
from mavscope.transport import tcp
from tests.support import tcpflows as tf
from tests.support.flows import Sender, heartbeat

ENGINES = ({"MAVSCOPE_PURE": "0"}, {"MAVSCOPE_PURE": "1"})


def stopped_stream(tmp: Path, later: list[float]) -> Path:
    """The vehicle's TCP stream of 5 HEARTBEATs at t = 0..4, the one of t=3 missed (no ACKs captured), each
    followed 0.5 s later by a datagram of another vehicle 2/1; then the TCP stream says nothing more and 2/1
    goes on at the times `later`. Records: 1-3 the handshake; 4 (t=0), 6, 8 the segments of t=0, 1, 2; 5, 7,
    9, 10 the datagrams of t=0.5, 1.5, 2.5, 3.5; 11 the segment of t=4, 12 its datagram (4.5); 13... `later`."""
    other = Sender(2, 1)
    cap = tf.build(tf.one_per_segment(tf.heartbeats(5)), missed={3}, acks=False,
                   udp=[other.pack(heartbeat()) for _ in range(5)])
    assert (cap.record_of[4], cap.udp_of[4]) == (11, 12)
    for t in later:
        cap.datagram(other.pack(heartbeat()), t)
    return cap.write(tmp / "stopped.pcap")


def test_a_hole_among_udp_traffic_is_given_up_by_the_capture_clock(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """2/1 goes on every 0.5 s from t=5 to 9.5 (records 13-22). The segment of t=4 (record 11) waits on the
    hole of t=3 since the clock of its arrival, 4.0: the first record more than 2 s later is the datagram of
    t=6.5 (record 16; t=6.0 is exactly 2 s). So its frame comes out there, after record 16's own frame, dated
    by record 11 and t=4, with a tcp-gap note of the 21 bytes missed (a v2 HEARTBEAT) that waited 2.5 s. Under
    the old rule it waited for a next TCP segment and came out at the capture's end, after record 22."""
    assert tcp.HOLE_TIMEOUT == 2.0
    path = stopped_stream(tmp_path, [5 + 0.5 * i for i in range(10)])
    outs = []
    for environ in ENGINES:
        cli.environ = environ
        frames = cli.jsonl(path)
        assert [f["frame"] for f in frames] == [4, 5, 6, 7, 8, 9, 10, 12, 13, 14, 15, 16, 11, 17, 18, 19, 20, 21, 22]
        late = frames[12]
        assert (late["frame"], late["time"], late["sysid"], late["seq"]) == (11, tf.T0 + 4, 1, 4)
        (gap,) = [n["message"] for n in late["notes"] if n["code"] == "tcp-gap"]
        assert gap.startswith("21 bytes missing") and "nothing filled them in 2.5 s" in gap
        outs.append([cli(*argv) for argv in (("read", path), ("read", path, "-T", "jsonl"), ("stats", path, "--json"))])
    assert outs[0] == outs[1]


def test_a_hole_while_the_clock_stands_still_is_given_up_after_hole_records(  # type: ignore[no-untyped-def]
        cli, tmp_path: Path, dialect, monkeypatch: pytest.MonkeyPatch) -> None:
    """2/1 sends 1,000 datagrams all at t=4.5 (records 13-1012): the clock never passes the hole's 2 s. With
    HOLE_RECORDS lowered to 8, the hole (waited for since record 11) is given up at the first record more than 8
    records later, record 20: the frame of record 11 comes out there, after record 20's own. The dissector's
    table of frame indices (kept while a hole may date frames by a record) then shrinks: after the 1,012
    records it holds fewer than 100 entries (under the old rule the hole held it at one a record: 1,000)."""
    monkeypatch.setattr(tcp, "HOLE_RECORDS", 8)
    path = stopped_stream(tmp_path, [4.5] * 1000)
    d = Dissector(dialect)
    order = []
    with open_capture(path) as reader:
        for rec in reader:
            order += [f.record for f in d.feed(rec) if isinstance(f, Frame)]
    order += [f.record for f in d.finish() if isinstance(f, Frame)]
    assert order[:16] == [4, 5, 6, 7, 8, 9, 10, 12, 13, 14, 15, 16, 17, 18, 19, 20] and order[16] == 11
    assert order[17:] == list(range(21, 1013))
    assert len(d._indices) < 100
    outs = []
    for environ in ENGINES:
        cli.environ = environ
        frames = cli.jsonl(path)
        assert [f["frame"] for f in frames][:18] == [*order[:17], 21]
        gap = [n["message"] for f in frames for n in f.get("notes", ()) if n["code"] == "tcp-gap"]
        assert len(gap) == 1 and "nothing filled them in 8 records" in gap[0]
        outs.append((cli("read", path), json.loads(cli("stats", path, "--json").out)))
    assert outs[0] == outs[1]
