"""Writers: round trips through mavscope's readers and scapy's, and the synthetic UDP helper."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import pytest

from mavscope.capture.base import LINKTYPE_ETHERNET, LINKTYPE_RAW
from mavscope.capture.detect import open_capture
from mavscope.capture.synth import udp_packet
from mavscope.capture.writer import PcapngWriter, PcapWriter
from mavscope.errors import UsageError
from mavscope.transport.decap import Decapsulator

T0 = 1_700_000_000.125
PACKETS = [udp_packet("10.0.0.1", 14550, "10.0.0.2", 14540, bytes([i]) * (i + 1)) for i in range(5)]


@pytest.mark.parametrize("ns", [False, True])
def test_pcap_round_trip(tmp_path: Path, ns: bool) -> None:
    path = tmp_path / "out.pcap"
    with PcapWriter(path, LINKTYPE_ETHERNET, nanosecond=ns) as w:
        for i, p in enumerate(PACKETS):
            w.write(T0 + i * 0.001, p)
        w.write(None, b"\x01" * 10, orig_len=1500)
    with open_capture(path) as r:
        recs = list(r)
    assert [rec.data for rec in recs] == PACKETS + [b"\x01" * 10]
    assert recs[1].time == pytest.approx(T0 + 0.001, abs=1e-6)
    assert recs[-1].orig_len == 1500 and recs[-1].notes[0].code == "record-snapped"

    from scapy.utils import rdpcap

    pkts = rdpcap(str(path))
    assert [bytes(p) for p in pkts][:5] == PACKETS
    assert float(pkts[1].time) == pytest.approx(T0 + 0.001, abs=1e-6)


def test_pcap_snaplen_and_fileobj() -> None:
    buf = io.BytesIO()
    w = PcapWriter(buf, LINKTYPE_RAW, snaplen=8)
    w.write(1.9999999, b"0123456789")
    w.flush()
    w.close()
    assert not buf.closed  # a caller's file object stays open
    sec, frac, incl, orig = struct.unpack_from("<IIII", buf.getvalue(), 24)
    assert (sec, frac, incl, orig) == (2, 0, 8, 10)  # rounding carries into the seconds
    with pytest.raises(UsageError):
        w.write(1.0, b"x")


def test_pcapng_several_linktypes_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "out.pcapng"
    with PcapngWriter(path, nanosecond=True) as w:
        w.write(T0, PACKETS[0], linktype=LINKTYPE_ETHERNET)
        w.write(T0 + 1, PACKETS[1][14:], linktype=LINKTYPE_RAW)
        w.write(T0 + 2, PACKETS[2], linktype=LINKTYPE_ETHERNET)
    with open_capture(path) as r:
        recs = list(r)
        assert r.kind == "pcapng" and len(r.interfaces) == 2
    assert [(rec.linktype, rec.data) for rec in recs] == [
        (LINKTYPE_ETHERNET, PACKETS[0]), (LINKTYPE_RAW, PACKETS[1][14:]), (LINKTYPE_ETHERNET, PACKETS[2])]
    assert recs[1].time == pytest.approx(T0 + 1, abs=1e-6)
    d = Decapsulator()
    assert [p.data for rec in recs for p in d.feed(rec)] == [bytes([0]), bytes([1]) * 2, bytes([2]) * 3]

    from scapy.utils import PcapNgReader

    with PcapNgReader(str(path)) as r:
        pkts = list(r)
    assert [bytes(p) for p in pkts] == [rec.data for rec in recs]
    assert float(pkts[2].time) == pytest.approx(T0 + 2, abs=1e-6)


def test_pcapng_needs_a_linktype() -> None:
    with pytest.raises(UsageError):
        PcapngWriter(io.BytesIO()).write(0.0, b"x")


def test_synth_udp_checksums_verified_by_scapy() -> None:
    from scapy.layers.inet import IP, UDP
    from scapy.layers.l2 import Ether

    raw = udp_packet("192.168.1.2", 45815, "192.168.1.1", 14550, b"\xfd\x09payload")
    pkt = Ether(raw)
    assert pkt[IP].src == "192.168.1.2" and pkt[UDP].dport == 14550 and bytes(pkt[UDP].payload) == b"\xfd\x09payload"
    ip_sum, udp_sum = pkt[IP].chksum, pkt[UDP].chksum
    del pkt[IP].chksum, pkt[UDP].chksum
    rebuilt = Ether(bytes(pkt))
    assert (rebuilt[IP].chksum, rebuilt[UDP].chksum) == (ip_sum, udp_sum)
    with pytest.raises(UsageError):
        udp_packet("localhost", 1, "1.2.3.4", 5, b"")
    with pytest.raises(UsageError):
        udp_packet("1.2.3.4", 1, "1.2.3.5", 5, bytes(0x10000))
