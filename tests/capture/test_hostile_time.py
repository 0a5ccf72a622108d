"""Record times that cannot be real times (defect 4): readers keep the raw number, writers clamp and say so.

A pcapng interface may say `if_tsoffset` = 2**62 or -2**62 seconds, `if_tsresol` = 1 s with a 64-bit
timestamp, or an EPB's high word may put the time past the year 9999. The readers yield the time the
file states (a finite float, whatever its range; never an exception); `read -w x.pcapng` used to raise
struct.error on such a time and `-w x.pcap` silently wrapped the seconds. The writers now clamp to what
their format holds and count it (`clamped`, `clamp_message()`).
"""

from __future__ import annotations

import io
import math
import struct
from pathlib import Path

import pytest

from mavscope.capture.base import LINKTYPE_ETHERNET
from mavscope.capture.detect import open_capture
from mavscope.capture.synth import udp_packet
from mavscope.capture.writer import PcapngWriter, PcapWriter
from tests.conftest import Cli
from tests.support.builders import pcapng_epb, pcapng_idb, pcapng_shb
from tests.support.pmav import heartbeat, mav2

T0 = 1_700_000_000
PACKET = udp_packet("10.0.0.1", 14550, "10.0.0.2", 14540, heartbeat(mav2()))
PCAP_LAST = (1 << 32) - 1  # the last second a pcap record holds
DATETIME_LAST = 253_402_300_799  # 9999-12-31T23:59:59Z


def _pcapng(options: bytes, ticks: list[int]) -> bytes:
    """One Ethernet interface (snaplen 65535) with `options` as given, a packet of PACKET at each of `ticks`."""
    idb = pcapng_idb(LINKTYPE_ETHERNET, snaplen=65535, options=options)
    return pcapng_shb() + idb + b"".join(pcapng_epb(0, t, PACKET) for t in ticks)


TSOFFSET = 14
TSRESOL = 9
CASES = {
    # name: (IDB options, EPB ticks, the times the reader yields)
    "huge if_tsoffset": (struct.pack("<HHq", TSOFFSET, 8, 2**62), [T0 * 10**6], [T0 + 2**62]),
    "negative if_tsoffset": (struct.pack("<HHq", TSOFFSET, 8, -(2**62)), [T0 * 10**6], [T0 - 2**62]),
    "1 s resolution": (struct.pack("<HHB3x", TSRESOL, 1, 0), [2**63, 2**64 - 1], [2.0**63, 2.0**64]),
    "EPB high word past 9999": (b"", [60_000_000 << 32, 0xFFFFFFFF << 32],
                                [(60_000_000 << 32) / 1e6, (0xFFFFFFFF << 32) / 1e6]),
    "ns past 2106, before 9999": (struct.pack("<HHB3x", TSRESOL, 1, 9), [5_000_000_000 * 10**9], [5e9]),
}


@pytest.mark.parametrize("name", CASES)
def test_readers_keep_the_raw_time(tmp_path: Path, name: str) -> None:
    options, ticks, times = CASES[name]
    path = tmp_path / "t.pcapng"
    path.write_bytes(_pcapng(options, ticks))
    with open_capture(path) as reader:
        records = list(reader)
    assert [r.time for r in records] == pytest.approx(times, rel=1e-12)
    assert all(r.time is not None and math.isfinite(r.time) for r in records)
    # a time outside the calendar is noted on its record (the "ns past 2106" one is a calendar date)
    for r in records:
        assert r.time is not None
        outside = not 0 <= r.time <= DATETIME_LAST
        assert [n.code for n in r.notes] == (["time-out-of-range"] if outside else []), (r.time, r.notes)


def _written_times(content: bytes, tmp_path: Path) -> list[float | None]:
    path = tmp_path / "written.cap"
    path.write_bytes(content)
    with open_capture(path) as reader:
        return [r.time for r in reader]


@pytest.mark.parametrize("nanosecond", [False, True])
def test_pcap_writer_clamps_instead_of_wrapping(tmp_path: Path, nanosecond: bool) -> None:
    units = 10**9 if nanosecond else 10**6
    times = [T0 + 0.5, 2.0**63, -(2.0**62), float("nan"), float("inf"), -math.inf, (1 << 32) - 1e-10, None,
             float(1 << 32)]
    buf = io.BytesIO()
    w = PcapWriter(buf, LINKTYPE_ETHERNET, nanosecond=nanosecond)
    for t in times:
        w.write(t, PACKET)
    last = PCAP_LAST + (units - 1) / units
    assert _written_times(buf.getvalue(), tmp_path) == pytest.approx(
        [T0 + 0.5, last, 0.0, 0.0, last, 0.0, last, 0.0, last], rel=1e-15)
    assert w.clamped == 7
    msg = w.clamp_message()
    assert msg is not None and "7 record times were written clamped" in msg and "2106-02-07T06:28:15Z" in msg
    assert "9.22337e+18 s" in msg  # the first one


@pytest.mark.parametrize("nanosecond", [False, True])
def test_pcapng_writer_clamps_instead_of_raising(tmp_path: Path, nanosecond: bool) -> None:
    units = 10**9 if nanosecond else 10**6
    last = ((1 << 64) - 1) / units
    buf = io.BytesIO()
    w = PcapngWriter(buf, LINKTYPE_ETHERNET, nanosecond=nanosecond)
    for t in (2.0**63, -1.0, float("nan"), T0 + 0.25, 2.0**62 / units):
        w.write(t, PACKET)
    assert w.clamped == 3
    assert _written_times(buf.getvalue(), tmp_path) == pytest.approx([last, 0.0, 0.0, T0 + 0.25, 2.0**62 / units])
    assert "3 record times were written clamped: pcapng cannot hold" in (w.clamp_message() or "")
    clean = PcapngWriter(io.BytesIO(), LINKTYPE_ETHERNET)
    clean.write(T0, PACKET)
    clean.write(None, PACKET)  # no time at all is not a clamp
    assert clean.clamped == 0 and clean.clamp_message() is None


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("suffix", [".pcap", ".pcapng"])
def test_read_w_copies_any_time_without_crashing(cli: Cli, tmp_path: Path, name: str, suffix: str) -> None:
    options, ticks, times = CASES[name]
    src = tmp_path / "in.pcapng"
    src.write_bytes(_pcapng(options, ticks))
    out = tmp_path / f"out{suffix}"
    status, _, err = cli("read", src, "-q", "-w", out)
    assert status == 0, err
    limit = PCAP_LAST + 0.999999 if suffix == ".pcap" else ((1 << 64) - 1) / 1e6
    clamped = sum(not 0 <= t <= limit for t in times)
    # the user is told, once, that times were clamped (and how many)
    warnings = [line for line in err.splitlines() if line.startswith(f"mavscope: warning: -w {out}: ")]
    assert len(warnings) == bool(clamped), err
    if clamped:
        assert f"{clamped} record time" in warnings[0] and "written clamped" in warnings[0]
    written = _written_times(out.read_bytes(), tmp_path)
    assert len(written) == len(times)
    for t, w in zip(times, written, strict=True):
        assert w is not None and 0 <= w
        if suffix == ".pcap":
            assert w == pytest.approx(min(max(t, 0), PCAP_LAST + 0.999999))  # clamped, never wrapped
        else:
            assert w == pytest.approx(min(max(t, 0), ((1 << 64) - 1) / 1e6))


def test_tlog_writer_clamps_too(tmp_path: Path) -> None:
    """A tlog entry's time is 64-bit microseconds: NaN, negative and far-future times are clamped and counted;
    read back by pymavlink's own tlog reader (mavutil), which takes the first 8 bytes as big-endian usec."""
    from pymavlink import mavutil

    from mavscope.capture.writer import TlogWriter

    path = tmp_path / "t.tlog"
    frame = heartbeat(mav2())
    with TlogWriter(path) as w:
        for t in (float("nan"), -5.0, 1e30, T0 + 0.5):
            w.write(t, frame)
    assert w.clamped == 3 and "3 record times were written clamped: a tlog cannot hold" in (w.clamp_message() or "")
    log = mavutil.mavlink_connection(str(path), dialect="common")
    stamps = []
    while (msg := log.recv_match()) is not None:
        stamps.append(msg._timestamp)
    assert stamps == pytest.approx([0.0, 0.0, ((1 << 64) - 1) / 1e6, T0 + 0.5])


def test_read_w_refuses_an_unwritable_output_before_reading(cli: Cli, tmp_path: Path) -> None:
    """An output that cannot be opened is a one-line error at once (not after reading the whole capture)."""
    src = tmp_path / "in.pcapng"
    src.write_bytes(_pcapng(b"", [T0 * 10**6]))
    status, out, err = cli("read", src, "-w", tmp_path / "no-such-dir" / "out.pcap")
    assert status != 0 and out == ""
    assert err.startswith("mavscope: ") and "cannot write" in err and err.count("\n") == 1


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("command", [["stats"], ["timeline"], ["commands"], ["mission"], ["audit"],
                                     ["verify", "--key", "passphrase:x"], ["events"],
                                     ["track", "--gpx", "/dev/null", "--kml", "/dev/null", "--geojson", "/dev/null"],
                                     ["plot", "mavlink.seq"]])
def test_reports_print_any_time(cli: Cli, tmp_path: Path, name: str, command: list[str]) -> None:
    """Text reports format capture times as calendar dates; one outside the calendar must not crash them
    (stats and timeline raised OverflowError before)."""
    options, ticks, _ = CASES[name]
    src = tmp_path / "in.pcapng"
    src.write_bytes(_pcapng(options, ticks))
    status, _, err = cli(command[0], src, *command[1:])
    assert status in (0, 1) and "Traceback" not in err, err
    assert cli(command[0], src, *command[1:], "--json").status in (0, 1)


def test_a_time_note_per_record_is_capped_on_stderr(cli: Cli, tmp_path: Path) -> None:
    """Every record of a hostile file may carry a capture note: stderr shows the first Problems.LIMIT of a
    code and one line with how many more; the JSON of each frame still carries its note."""
    from mavscope.commands.common import Problems

    src = tmp_path / "in.pcapng"
    options, _, _ = CASES["huge if_tsoffset"]
    src.write_bytes(_pcapng(options, [T0 * 10**6 + i for i in range(50)]))
    status, out, err = cli("read", src, "-T", "jsonl")
    assert status == 0
    lines = err.splitlines()
    assert len(lines) == Problems.LIMIT + 1, err
    assert lines[-1].endswith(f"{50 - Problems.LIMIT} more time-out-of-range problems not shown (50 in all)")
    assert out.count('"time-out-of-range"') == 50
