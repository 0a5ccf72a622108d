"""The benchmark capture over TCP: `tcp_bench.py N OUT` writes the N-frame bench pcap's MAVLink as one TCP
connection (`.venv/bin/python benchmarks/tcp_bench.py 200000 benchmarks/out/tcp_200000.pcap`).

The datagrams of bench_capture.py (vehicle 10.0.0.2:14580 and GCS 10.0.0.1:14550, generated once and cached
in benchmarks/out/) become the segments of a connection between the same ends, after a handshake: each
datagram's payload is one segment of its sender's direction, at its time, acknowledging every byte of the
other direction so far (as a peer sending its own data does); every 10th is cut in two segments, so frames
also span records. Nothing is lost or out of order: this times TCP reassembly's common path (`read` of
`mavscope.transport.tcp` and `StreamFramer`), docs/performance.md ("TCP streams").
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_capture import _ip_checksum, capture  # noqa: E402

_REC = struct.Struct("<IIII")
_IP = struct.Struct("!BBHHHBBH4s4s")
_TCP = struct.Struct("!HHIIBBHHH")
ISN = {14580: 1_000, 14550: 900_000}  # per sender port


def _packet(eth: bytes, src: bytes, dst: bytes, sport: int, dport: int, seq: int, ack: int, flags: int,
            data: bytes, ipid: int) -> bytes:
    tcp = _TCP.pack(sport, dport, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4, flags, 65535, 0, 0)
    seg = tcp + data
    words = src + dst + struct.pack("!BBH", 0, 6, len(seg)) + seg + b"\0" * (len(seg) & 1)
    s = sum(struct.unpack(f"!{len(words) // 2}H", words))
    while s >> 16:
        s = (s & 0xFFFF) + (s >> 16)
    seg = seg[:16] + struct.pack("!H", ~s & 0xFFFF) + seg[18:]
    iph = _IP.pack(0x45, 0, 40 + len(data), ipid, 0x4000, 64, 6, 0, src, dst)
    iph = iph[:10] + struct.pack("!H", _ip_checksum(iph)) + iph[12:]
    return eth + iph + seg


def convert(udp_pcap: Path, out: Path) -> int:
    """Write `udp_pcap`'s datagrams as one TCP connection to `out`; the number of records written."""
    buf = udp_pcap.read_bytes()
    res = bytearray(buf[:24])
    nxt: dict[int, int] = {}  # sender port -> next sequence number
    pos, ipid, n, first = 24, 0, 0, True
    while pos < len(buf):
        sec, usec, incl, _ = _REC.unpack_from(buf, pos)
        pkt = buf[pos + 16:pos + 16 + incl]
        pos += 16 + incl
        eth, src, dst = pkt[:14], pkt[26:30], pkt[30:34]
        sport, dport = struct.unpack_from("!HH", pkt, 34)
        data = pkt[42:]
        if first:  # the GCS (14550) opens the connection to the vehicle (14580)
            first = False
            for s, d, flags, ack in ((14550, 14580, 0x02, 0), (14580, 14550, 0x12, ISN[14550] + 1),
                                     (14550, 14580, 0x10, ISN[14580] + 1)):
                a, b = (dst, src) if s == dport else (src, dst)
                p = _packet(eth, a, b, s, d, ISN[s] + (0 if flags & 0x02 else 1), ack, flags, b"", ipid)
                res += _REC.pack(sec, usec, len(p), len(p)) + p
                n += 1
                ipid += 1
            nxt = {14580: ISN[14580] + 1, 14550: ISN[14550] + 1}
        pieces = [data[:len(data) // 2], data[len(data) // 2:]] if n % 10 == 0 and len(data) > 1 else [data]
        for piece in pieces:
            ipid = (ipid + 1) & 0xFFFF
            p = _packet(eth, src, dst, sport, dport, nxt[sport], nxt[dport], 0x18, piece, ipid)
            nxt[sport] += len(piece)
            res += _REC.pack(sec, usec, len(p), len(p)) + p
            n += 1
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(res)
    return n


def main() -> None:
    frames, out = int(sys.argv[1]), Path(sys.argv[2])
    cache = Path(__file__).resolve().parent / "out"
    cache.mkdir(exist_ok=True)
    udp, _ = capture(cache, frames)
    print(f"{out}: {convert(udp, out)} records")


if __name__ == "__main__":
    main()
