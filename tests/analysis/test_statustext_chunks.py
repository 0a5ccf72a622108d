"""STATUSTEXT chunks joined as QGroundControl joins them (issue 35, item 13), in `events` (and so the TUI's
events screen), missing chunks said; each chunk's Info line says which chunk of which id it is.

The rule, read from QGroundControl (mavlink/qgroundcontrol src/MAVLink/StatusTextHandler.cc,
`_handleStatusText`, `_chunkedStatusTextTimeout`, `_chunkedStatusTextCompleted`): one text in progress per
sender; id 0 is whole; another id ends the text in progress; a chunk_seq past the next fills the chunks
between as missing; a chunk whose text is shorter than 50 bytes (it holds a NUL: common.xml's "any null
character in the text field is taken to mean this was the last chunk") completes the text; 1 s without a
chunk ends it with its end missing. Every expected text below is written by hand from the chunks the test
builds (QGroundControl's " ... " for a missing chunk being mavscope's "[chunk k missing]" and "[end not
seen]", docs/analysis.md).
"""

from __future__ import annotations

from pathlib import Path

from mavscope.analysis.events import story
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import Cli
from tests.native.engines import same
from tests.support import flows
from tests.support.flows import T0, Sender, write_tlog, write_udp_pcap

v2 = flows.v2
A50 = b"Failsafe enabled: no manual control and no offboar"  # 50 bytes: not the last chunk
B50 = b"PreArm: Battery below minimum arming voltage, chec"  # 50 bytes


def st(sev: int, text: bytes, ident: int = 0, seq: int = 0) -> object:
    return v2.MAVLink_statustext_message(sev, text, ident, seq)


def _texts(path: str, dialect: Dialect) -> list[tuple[int, tuple[int, int], str, dict]]:
    with open_capture(path) as r:
        events = story((f for f in Dissector(dialect).run(r) if type(f) is not Anomaly), dialect).events
    return [(e.frame, e.sender, str(e.details["message"]), e.details) for e in events
            if e.kind == "statustext" or e.details.get("source") == "STATUSTEXT"]


def test_two_chunks_make_one_text(tmp_path: Path, dialect: Dialect) -> None:
    assert len(A50) == 50 and len(B50) == 50
    s = Sender(1, 1)
    path = write_tlog(tmp_path, [(T0, s.pack(st(2, A50, 7, 0))), (T0 + 0.01, s.pack(st(2, b"d control", 7, 1)))])
    ((frame, sender, text, d),) = _texts(path, dialect)
    assert (frame, sender, text) == (1, (1, 1), "Failsafe enabled: no manual control and no offboard control")
    assert (d["id"], d["chunks"], d["frames"], d["complete"], d["end"], d["severity"]) == (
        7, 2, [1, 2], True, "last-chunk", "CRITICAL")
    assert "missing" not in d


def test_interleaved_senders_are_joined_apart(tmp_path: Path, dialect: Dialect) -> None:
    # two senders (1/1 and 2/1), both with id 3, their chunks alternating: each text is its own sender's
    a, b = Sender(1, 1), Sender(2, 1)
    entries = [(T0, a.pack(st(4, B50, 3, 0))), (T0 + 0.01, b.pack(st(4, A50, 3, 0))),
               (T0 + 0.02, a.pack(st(4, b"k voltage", 3, 1))), (T0 + 0.03, b.pack(st(4, b"d control", 3, 1)))]
    got = [(f, s, t) for f, s, t, _ in _texts(write_tlog(tmp_path, entries), dialect)]
    assert got == [(1, (1, 1), "PreArm: Battery below minimum arming voltage, check voltage"),
                   (2, (2, 1), "Failsafe enabled: no manual control and no offboard control")]


def test_a_missing_chunk_is_said(tmp_path: Path, dialect: Dialect) -> None:
    # chunk 1 of id 9 never arrives; chunk 2 ends the text (a NUL in its 50 bytes)
    s = Sender(1, 1)
    entries = [(T0, s.pack(st(2, A50, 9, 0))), (T0 + 0.02, s.pack(st(2, b"no connection", 9, 2)))]
    ((_, _, text, d),) = _texts(write_tlog(tmp_path, entries), dialect)
    assert text == A50.decode() + "[chunk 1 missing]no connection"
    assert (d["missing"], d["complete"], d["end"], d["chunks"]) == ([1], False, "last-chunk", 2)


def test_missing_first_chunks_and_a_missing_end(tmp_path: Path, dialect: Dialect) -> None:
    # the capture holds chunks 2 and 3 of id 5 only, chunk 3 full (no NUL): the start and the end are missing
    s = Sender(1, 1)
    entries = [(T0, s.pack(st(6, B50, 5, 2))), (T0 + 0.01, s.pack(st(6, A50, 5, 3)))]
    ((_, _, text, d),) = _texts(write_tlog(tmp_path, entries), dialect)
    assert text == "[chunks 0-1 missing]" + B50.decode() + A50.decode() + "[end not seen]"
    assert (d["missing"], d["end"]) == ([0, 1], "capture-end")


def test_id_zero_is_whole_even_at_50_bytes(tmp_path: Path, dialect: Dialect) -> None:
    # id 0: "the only chunk in the sequence and the message can be emitted immediately"; the next text is
    # another message even though the first had no NUL
    s = Sender(1, 1)
    entries = [(T0, s.pack(st(6, A50))), (T0 + 0.01, s.pack(st(6, b"d control")))]
    got = [(f, t, d.get("id")) for f, _, t, d in _texts(write_tlog(tmp_path, entries), dialect)]
    assert got == [(1, A50.decode(), None), (2, "d control", None)]


def test_another_id_or_a_second_of_silence_ends_a_text(tmp_path: Path, dialect: Dialect) -> None:
    s = Sender(1, 1)
    entries = [(T0, s.pack(st(6, A50, 1, 0))),  # id 1 never ends: id 2 begins
               (T0 + 0.1, s.pack(st(6, B50, 2, 0))),  # id 2's chunk 1 comes 1.5 s later: a timeout
               (T0 + 1.6, s.pack(st(6, b"k voltage", 2, 1)))]
    got = [(f, t, d["end"]) for f, _, t, d in _texts(write_tlog(tmp_path, entries), dialect)]
    assert got == [(1, A50.decode() + "[end not seen]", "next-id"), (2, B50.decode() + "[end not seen]", "timeout"),
                   (3, "[chunk 0 missing]k voltage", "last-chunk")]


def test_a_copy_of_a_chunk_counts_once_and_utf8_is_joined_whole(tmp_path: Path, dialect: Dialect) -> None:
    # "°" (c2 b0) split over the chunks: 49 ASCII bytes and c2, then b0 and the rest; chunk 0 arrives twice
    s = Sender(1, 1)
    first = b"Temperature of the flight controller too high: 85" + b"\xc2"
    c0 = s.pack(st(4, first, 4, 0))
    entries = [(T0, c0), (T0 + 0.001, c0), (T0 + 0.01, s.pack(st(4, b"\xb0C", 4, 1)))]
    ((_, _, text, d),) = _texts(write_tlog(tmp_path, entries), dialect)
    assert text == "Temperature of the flight controller too high: 85°C"
    assert (d["chunks"], d["frames"]) == (2, [1, 3])


def test_cli_events_and_info_column_both_engines(tmp_path: Path, cli: Cli) -> None:
    s = Sender(1, 1)
    frames = [s.pack(st(2, A50, 7, 0)), s.pack(st(2, b"d control", 7, 1)), s.pack(st(6, b"plain"))]
    pcap = str(write_udp_pcap(tmp_path / "st.pcap", [(("10.0.0.2", 14555), ("10.0.0.1", 14550), f) for f in frames]))
    tlog = write_tlog(tmp_path, [(T0 + i * 0.01, f) for i, f in enumerate(frames)])
    for path in (pcap, tlog):
        lines = same(cli, path, fmt=()).out.splitlines()
        assert lines[0].endswith("[chunk 0 of id 7]") and lines[1].endswith("text='d control' [chunk 1 of id 7]")
        assert lines[2].endswith("text='plain'")
        same(cli, path)  # JSON Lines: the fields as sent
    doc = cli.json("events", tlog)  # (the pcap's datagrams are a second apart: QGroundControl's timeout)
    texts = [e["details"]["message"] for e in doc["events"] if e["kind"] in ("statustext", "failsafe")]
    assert texts == ["Failsafe enabled: no manual control and no offboard control", "plain"]
