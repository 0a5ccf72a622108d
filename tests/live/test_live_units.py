"""The live capture parts on their own: queue and kernel drop accounting, the pcap sink, endpoints."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import pytest

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.capture.detect import open_capture
from mavscope.capture.synth import udp_packet
from mavscope.errors import UsageError
from mavscope.live import LivePcapWriter, UdpSource, parse_endpoint
from mavscope.live.drops import proc_udp_drops, socket_inode
from tests.support import pmav


def _drain(src: UdpSource) -> list[Record]:
    return list(src.records())


def _send(port: int, n: int, payload: bytes) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for _ in range(n):
            s.sendto(payload, ("127.0.0.1", port))


def test_queue_overflow_is_counted_never_silent() -> None:
    src = UdpSource(parse_endpoint("127.0.0.1:0", what="--udp"), max_items=10)
    src.open()
    src.start()
    try:
        _send(src.local[1], 50, pmav.heartbeat(pmav.mav2()))
        deadline = time.monotonic() + 5
        while src.received < 50 and time.monotonic() < deadline:
            time.sleep(0.01)
        src.stop()
        records = _drain(src)  # nobody consumed while they arrived: only 10 fitted
    finally:
        src.close()
    st = src.stats()
    assert len(records) == 10 and st.delivered == 10
    assert st.received == 50 and st.queue_drops == 40 and st.dropped >= 40
    assert [r.number for r in records] == list(range(1, 11))


def test_kernel_drops_are_counted() -> None:
    """A tiny socket buffer and no receiver running yet: the kernel drops, and the source says so."""
    src = UdpSource(parse_endpoint("127.0.0.1:0", what="--udp"), rcvbuf=4096)
    src.open()
    try:
        sent = 300
        _send(src.local[1], sent, pmav.statustext(pmav.mav2(), "x" * 40))
        src.start()
        time.sleep(0.3)
        src.stop()
        records = _drain(src)
    finally:
        src.close()
    kernel = src.kernel_drops()
    assert kernel is not None and kernel > 0
    assert len(records) + kernel == sent  # every datagram is either delivered or counted as dropped
    assert src.stats().queue_drops == 0


def test_proc_udp_drops_reads_the_socket_line() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        value = proc_udp_drops(socket_inode(s))
    if value is None:
        pytest.skip("/proc/net/udp is not available here")
    assert value == 0
    assert proc_udp_drops(1) is None


def test_records_are_numbered_with_pcap_offsets() -> None:
    src = UdpSource(parse_endpoint("127.0.0.1:0", what="--udp"))
    src.open()
    src.start()
    try:
        _send(src.local[1], 3, pmav.heartbeat(pmav.mav2()))
        time.sleep(0.2)
        src.stop()
        records = _drain(src)
    finally:
        src.close()
    assert [r.number for r in records] == [1, 2, 3]
    size = len(records[0].data)
    assert [r.offset for r in records] == [40, 40 + 16 + size, 40 + 2 * (16 + size)]  # as in the -w pcap
    assert src.t0 == records[0].time


def test_sink_flushes_on_tick(tmp_path: Path) -> None:
    out = tmp_path / "f.pcap"
    w = LivePcapWriter(str(out), LINKTYPE_ETHERNET, flush_interval=0.2)
    pkt = udp_packet("127.0.0.1", 1, "127.0.0.1", 14550, pmav.heartbeat(pmav.mav2()))
    w.write(Record(1, time.time(), LINKTYPE_ETHERNET, pkt, 40, len(pkt)))
    time.sleep(0.25)
    w.tick()
    assert out.stat().st_size == 24 + 16 + len(pkt)  # on its way to disk while the writer is open
    w.close()


def test_sink_ring_alternates_two_files(tmp_path: Path) -> None:
    out = tmp_path / "r.pcap"
    (tmp_path / "r.pcap.1").write_bytes(b"stale")
    w = LivePcapWriter(str(out), LINKTYPE_ETHERNET, ring_mb=0.1)
    assert not (tmp_path / "r.pcap.1").exists()  # an earlier run's older half is not mixed in
    mav = pmav.mav2()
    for i in range(3000):
        pkt = udp_packet("127.0.0.1", 1, "127.0.0.1", 14550, pmav.statustext(mav, f"{i:05d}"))
        w.write(Record(i + 1, 1_700_000_000 + i, LINKTYPE_ETHERNET, pkt, 0, len(pkt)))
    w.close()
    assert w.rotations > 1 and w.files() == [str(out) + ".1", str(out)]
    sizes = [Path(p).stat().st_size for p in w.files()]
    assert all(s <= 50_000 for s in sizes) and sum(sizes) <= 100_000
    times = []
    for p in w.files():
        with open_capture(p) as r:
            times += [rec.time for rec in r]
    assert times == sorted(times) and times[-1] == 1_700_000_000 + 2999


def test_sink_ring_minimum() -> None:
    with pytest.raises(UsageError):
        LivePcapWriter("/nonexistent/x.pcap", LINKTYPE_ETHERNET, ring_mb=0.01)


def test_parse_endpoint() -> None:
    assert parse_endpoint("14550", what="--udp") == parse_endpoint("0.0.0.0:14550", what="--udp")
    e = parse_endpoint("localhost:14550", what="--forward", default_host=None)
    assert e.host == "127.0.0.1" and e.port == 14550 and e.family == socket.AF_INET
    v6 = parse_endpoint("[::1]:5", what="--udp")
    assert v6.family == socket.AF_INET6 and str(v6) == "[::1]:5"
    for bad in ("x", "1:2:3", "[::1]5", "99999"):
        with pytest.raises(UsageError):
            parse_endpoint(bad, what="--udp")


def test_synthesised_ipv6_checksums_verified_by_scapy() -> None:
    from scapy.layers.inet6 import UDP, IPv6
    from scapy.layers.l2 import Ether

    payload = pmav.heartbeat(pmav.mav2())
    pkt = Ether(udp_packet("::1", 40000, "fe80::1", 14550, payload))
    udp = pkt[UDP]
    sent = udp.chksum
    del udp.chksum
    assert Ether(bytes(pkt))[UDP].chksum == sent
    assert pkt[IPv6].plen == 8 + len(payload) and bytes(udp.payload) == payload
    # v4-mapped addresses on a dual-stack socket become plain IPv4
    assert udp_packet("::ffff:127.0.0.1", 1, "::ffff:127.0.0.1", 2, payload) == udp_packet(
        "127.0.0.1", 1, "127.0.0.1", 2, payload)
    # one end IPv4, the other IPv6: IPv6 with the IPv4 end mapped
    mixed = Ether(udp_packet("10.0.0.1", 1, "fe80::1", 2, payload))
    assert mixed[IPv6].src == "::ffff:10.0.0.1"


def test_stopper_decodes_a_little_longer_then_counts_what_it_leaves() -> None:
    """The first signal leaves STOP_DECODE_S of decoding; after it, and at once after a second signal,
    queued datagrams are counted as undecoded (they still go to the pcap). A fake clock: no timing."""
    from mavscope.live.stop import Stopper

    now = [100.0]
    s = Stopper(clock=lambda: now[0], grace=1.0)
    assert s.decode() and s.undecoded == 0  # running
    assert s.signal() is True  # the first stop: drain
    now[0] = 100.5
    assert s.decode()
    now[0] = 101.0
    assert not s.decode() and not s.decode() and s.undecoded == 2
    s2 = Stopper(clock=lambda: now[0], grace=1.0)
    s2.signal()
    assert s2.signal() is False and not s2.decode() and s2.undecoded == 1  # a second signal: stop now
