"""`read -T fields`: the forms tshark's cross-check (tests/crosscheck/test_tshark_fields.py) cannot show.

Captures built here with pymavlink (tests/support/builders.py); every expected line is written out by hand
from the frames put in: a datagram of two frames (occurrences), a STATUSTEXT whose text holds a tab, an
escape sequence and a quote (escaped, never raw: it cannot break a column or write to a terminal), a tlog
(no UDP fields: empty), a display filter (only the matched frames' values), payload fields by bare name
and from two messages, and `-q`.
"""

from __future__ import annotations

from pathlib import Path

from tests.conftest import Cli
from tests.support.builders import attitude, heartbeat, mav2, statustext, timed, write_tlog, write_udp_pcap

GCS, VEHICLE = ("10.0.0.1", 14550), ("10.0.0.2", 14580)


def _capture(tmp: Path) -> Path:
    # the sequence numbers given by hand (pymavlink's pack() does not advance them)
    return write_udp_pcap(tmp / "f.pcap", [
        (VEHICLE, GCS, heartbeat(mav2(1, 1, 0))),  # record 1: seq 0
        (VEHICLE, GCS, attitude(mav2(1, 1, 1), 1000, 0.5) + attitude(mav2(1, 1, 2), 1010, -0.25)),  # record 2
        (VEHICLE, GCS, statustext(mav2(1, 1, 3), 'a\tb\x1b[2J"c')),  # record 3: seq 3
    ])


def test_one_line_per_record_with_every_occurrence(cli: Cli, tmp_path: Path) -> None:
    path = str(_capture(tmp_path))
    got = cli("read", path, "-T", "fields", "-e", "frame.number", "-e", "mavlink.seq", "-e", "roll",
              "-e", "udp.srcport", "-e", "frame.index")
    assert got.status == 0, got.err
    assert got.out.splitlines() == ["1\t0\t\t14580\t1", "2\t1,2\t0.5,-0.25\t14580\t1,2", "3\t3\t\t14580\t1"]
    first = cli("read", path, "-T", "fields", "-e", "mavlink.seq", "-E", "occurrence=f")
    last = cli("read", path, "-T", "fields", "-e", "mavlink.seq", "-E", "occurrence=l", "-E", "aggregator=/s")
    assert first.out.splitlines() == ["0", "1", "3"] and last.out.splitlines() == ["0", "2", "3"]


def test_capture_text_is_escaped_and_quotes_doubled(cli: Cli, tmp_path: Path) -> None:
    path = str(_capture(tmp_path))
    got = cli("read", path, "-Y", "STATUSTEXT", "-T", "fields", "-e", "STATUSTEXT.text", "-e", "mavlink.seq",
              "-E", "quote=d", "-E", "header=y")
    assert got.status == 0, got.err
    # the tab and ESC as repr writes them (visible(): \t, \x1b), the quote doubled inside the quoted value
    assert got.out.splitlines() == ["STATUSTEXT.text\tmavlink.seq", '"a\\tb\\x1b[2J""c"\t"3"']
    assert "\x1b" not in got.out


def test_a_tlog_has_no_udp_fields_and_q_prints_nothing(cli: Cli, tmp_path: Path) -> None:
    v = mav2(1, 1)
    path = write_tlog(tmp_path, timed([heartbeat(v), attitude(v, 5, 0.125)], 1_700_000_000.0))
    got = cli("read", path, "-T", "fields", "-e", "frame.number", "-e", "udp.port", "-e", "ATTITUDE.roll",
              "-E", "separator=,")
    assert got.out.splitlines() == ["1,,", "2,,0.125"]
    assert cli("read", path, "-T", "fields", "-e", "frame.number", "-q").out == ""
