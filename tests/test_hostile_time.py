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
from mavscope.capture.writer import PcapngWriter, PcapWriter, synth_udp_ipv4
from mavscope.cli import Env, ExitStatus, main
from tests.pmav import heartbeat, mav2

T0 = 1_700_000_000
PACKET = synth_udp_ipv4("10.0.0.1:14550", "10.0.0.2:14540", heartbeat(mav2()))
PCAP_LAST = (1 << 32) - 1  # the last second a pcap record holds
DATETIME_LAST = 253_402_300_799  # 9999-12-31T23:59:59Z


def _block(btype: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) & 3)
    return struct.pack("<II", btype, 12 + len(body)) + body + struct.pack("<I", 12 + len(body))


def _pcapng(options: bytes, ticks: list[int]) -> bytes:
    shb = _block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
    idb = _block(1, struct.pack("<HHI", LINKTYPE_ETHERNET, 0, 65535) + options + struct.pack("<HH", 0, 0))
    epbs = b"".join(_block(6, struct.pack("<IIIII", 0, t >> 32, t & 0xFFFFFFFF, len(PACKET), len(PACKET)) + PACKET)
                    for t in ticks)
    return shb + idb + epbs


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
    assert all(r.time is not None and math.isfinite(r.time) and not r.notes for r in records)


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
def test_read_w_copies_any_time_without_crashing(tmp_path: Path, name: str, suffix: str) -> None:
    options, ticks, times = CASES[name]
    src = tmp_path / "in.pcapng"
    src.write_bytes(_pcapng(options, ticks))
    out = tmp_path / f"out{suffix}"
    err = io.StringIO()
    assert main(["read", str(src), "-q", "-w", str(out)], Env(stdout=io.StringIO(), stderr=err)) == ExitStatus.OK
    written = _written_times(out.read_bytes(), tmp_path)
    assert len(written) == len(times)
    for t, w in zip(times, written, strict=True):
        assert w is not None and 0 <= w
        if suffix == ".pcap":
            assert w == pytest.approx(min(max(t, 0), PCAP_LAST + 0.999999))  # clamped, never wrapped
        else:
            assert w == pytest.approx(min(max(t, 0), ((1 << 64) - 1) / 1e6))
