"""Seed corpora for the fuzz targets: the bundled captures (made by scripts/make_captures.py), and
examples of filters, key specs and TCP segment sequences."""

from __future__ import annotations

import shutil
import struct
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

FILTERS = (
    "mavlink_proto.msgid == 73", "COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH", "HEARTBEAT",
    'STATUSTEXT.text matches "^(a+)+$"', "ip.addr == 127.0.0.0/8 && !signature", "mavlink.seq in {1..10 20}",
    "signature.status == invalid || note.bad-crc", 'frame.time >= "2026-03-14T10:00:00Z"',
    "ftp.opcode == OpenFileRO", "mavlink.sysid & 0x80", "(((HEARTBEAT)))", "not not HEARTBEAT.type eq 2",
)
KEY_SPECS = (
    "hex:" + "4f" * 32, "passphrase:secret", "qgc:x", "base64:AAAA", "NAME=hex:00", "2=aes-128-ctr:hex:00#",
    "7=xor", "6=aes-gcm:ecdh", "2=xor:passphrase:#", "file:/nonexistent.toml", "hex:#", "#=", "1=aes-gcm:base64:#",
)


def tcp_seeds() -> list[bytes]:
    """A handshake, data in order, a retransmission, a gap, a FIN."""
    seg = struct.Struct("<BBIH")
    out = []
    data = b"\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00" + bytes(9) + b"\x00\x00"
    one = seg.pack(1, 0x02, 1000, 0) + seg.pack(1, 0x10, 1001, len(data)) + data
    one += seg.pack(1, 0x10, 1001, len(data)) + data + seg.pack(1, 0x10, 2000, 4) + b"abcd" + seg.pack(1, 0x01, 3000, 0)
    out.append(one)
    out.append(seg.pack(0, 0x02, 5, 0) + seg.pack(0, 0x02, 99, 0) + seg.pack(0, 0x10, 100, 3) + b"xyz")
    return out


def analyses_seeds() -> list[bytes]:
    """Byte strings the `analyses` target turns into frames (it reads choices from them): patterns, so
    that the first runs already give many frames of many messages."""
    return [bytes(range(256)) * 8, bytes(range(255, -1, -1)) * 8, b"\x00\x01\x02\x03" * 600, b"\x07" * 3000]


def export_seeds() -> list[bytes]:
    """The `export` target's inputs: a mode byte (keys, window, batch size: every combination across the
    seeds) and the first 6,000 bytes of a bundled capture (a cut capture is damage the sources must agree on)."""
    paths = sorted(p for p in (ROOT / "captures").iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
    return [bytes([i % 16]) + p.read_bytes()[:6000] for i, p in enumerate(paths)]


def fragment_seed() -> bytes:
    """A pcap of IP fragments (mavscope.transport.defrag): a UDP datagram of two HEARTBEATs in three IPv4
    fragments sent last to first, then fragments that overlap, and an IPv6 datagram in two fragments."""
    from tests.support.builders import pcap_bytes

    hb = b"\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00" + bytes(9) + b"\x00\x00"
    dgram = struct.pack("!HHHH", 14550, 14555, 8 + 2 * len(hb), 0) + hb * 2
    eth = b"\x02\x00\x00\x00\x00\x01\x02\x00\x00\x00\x00\x02"

    def v4(ident: int, off: int, more: bool, data: bytes) -> bytes:
        return eth + b"\x08\x00" + struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(data), ident,
                                              (0x2000 if more else 0) | off // 8, 64, 17, 0, b"\x0a\0\0\x02",
                                              b"\x0a\0\0\x01") + data

    def v6(ident: int, off: int, more: bool, data: bytes) -> bytes:
        return eth + b"\x86\xdd" + struct.pack("!IHBB16s16s", 6 << 28, 8 + len(data), 44, 64, bytes(15) + b"\x02",
                                              bytes(15) + b"\x01") + struct.pack("!BxHI", 17, off | more, ident) + data

    packets = [v4(1, 32, False, dgram[32:]), v4(1, 16, True, dgram[16:32]), v4(1, 0, True, dgram[:16]),
               v4(2, 16, True, dgram[16:32]), v4(2, 0, True, dgram[:16]), v4(2, 8, True, dgram[8:24]),
               v6(3, 0, True, dgram[:24]), v6(3, 24, False, dgram[24:])]
    return pcap_bytes((1.0 + i / 100, pkt) for i, pkt in enumerate(packets))


def wifi_seed() -> bytes:
    """A radiotap pcap (mavscope.transport.wifi): a QoS data frame with a HEARTBEAT, a protected frame, a
    beacon."""
    from scapy.layers.dot11 import Dot11, Dot11FCS, Dot11QoS, RadioTap
    from scapy.layers.inet import IP, UDP
    from scapy.layers.l2 import LLC, SNAP
    from scapy.packet import Raw

    hb = b"\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00" + bytes(9) + b"\x00\x00"
    mac = {"addr1": "02:00:00:00:00:01", "addr2": "02:00:00:00:00:02", "addr3": "02:00:00:00:00:01"}
    pkts = [RadioTap(present="TSFT+Flags", Flags="FCS") / Dot11FCS(type=2, subtype=8, FCfield="to_DS", **mac)
            / Dot11QoS() / LLC() / SNAP() / IP(src="192.168.4.2", dst="192.168.4.1")
            / UDP(sport=14550, dport=14555) / hb,
            RadioTap() / Dot11(type=2, FCfield="to_DS+protected", **mac) / Raw(bytes(40)),
            RadioTap() / Dot11(type=0, subtype=8) / Raw(b"beacon")]
    return _pcap(pkts, "wifi")


def wpa_seed() -> bytes:
    """A WPA2 capture (mavscope.transport.wpa, with the capture target's --wifi-key): a 4-way handshake,
    CCMP frames of both sides and group-addressed, a replay, a retransmission and an MSDU in fragments
    (tests/support/wpa.py)."""
    from tests.support import wpa as w

    hb = w.mavlink_packet(255, 0, arm=True)
    pkts = [*w.handshake(), w.ccmp_frame(w.AP, w.STA, 3, 1, hb),
            w.ccmp_frame(w.STA, w.AP, 3, 1, w.mavlink_packet(1, 0)),
            w.ccmp_frame(w.BROADCAST, w.AP, 4, 1, w.mavlink_packet(1, 1, dst="192.168.4.255"), key=w.GTK, key_index=1),
            w.ccmp_frame(w.AP, w.STA, 9, 1, hb), w.ccmp_frame(w.AP, w.STA, 9, 1, hb, retry=True),
            w.ccmp_frame(w.AP, w.STA, 10, 2, hb[:40], fragment=0, more=True),  # an MSDU in two fragments
            w.ccmp_frame(w.AP, w.STA, 10, 3, hb[40:], fragment=1)]
    return _pcap(pkts, "wpa")


def _pcap(pkts: list, name: str) -> bytes:  # type: ignore[type-arg]
    """The bytes of a pcap of scapy's `pkts` (written by scapy to a scratch file)."""
    # not builders.pcap_bytes: scapy's own writer, each packet's time and the link type taken from scapy's layers
    from scapy.utils import wrpcap

    path = ROOT / ".cache" / "fuzz" / f"{name}.tmp"
    path.parent.mkdir(parents=True, exist_ok=True)
    wrpcap(str(path), pkts)
    data = path.read_bytes()
    path.unlink()
    return data


def checksum_seed() -> bytes:
    """A pcap of checksums (mavscope.transport.checksum): UDP right, wrong, absent and an offload placeholder;
    IPv6 UDP with 0; a TCP stream with a segment of a wrong checksum before the right one."""
    from scapy.layers.inet import IP, TCP, UDP
    from scapy.layers.inet6 import IPv6
    from scapy.layers.l2 import Ether

    hb = b"\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00" + bytes(9) + b"\x00\x00"
    v4, v6 = IP(src="10.0.0.2", dst="10.0.0.1"), IPv6(src="fd00::2", dst="fd00::1")
    eth = Ether(src="02:00:00:00:00:02", dst="02:00:00:00:00:01")
    # UDP checksums: scapy's, a wrong one, none, and the pseudo-header's sum (offload) of this datagram
    pkts = [eth / v4 / UDP(sport=14550, dport=14555, chksum=c) / hb for c in (None, 0x1234, 0, 0x1431)]
    pkts += [eth / v6 / UDP(sport=14550, dport=14555, chksum=0) / hb,
             eth / v4 / TCP(sport=40000, dport=5760, flags="S", seq=9),
             eth / v4 / TCP(sport=40000, dport=5760, flags="PA", seq=10, chksum=0xBEEF) / hb[::-1],
             eth / v4 / TCP(sport=40000, dport=5760, flags="PA", seq=10) / hb]
    return _pcap(pkts, "checksums")


def write(corpus: Path) -> None:
    """Fill corpus/<target>/ with the seeds of each target."""
    cap = corpus / "capture"
    cap.mkdir(parents=True, exist_ok=True)
    for p in (ROOT / "captures").iterdir():
        if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"):
            shutil.copyfile(p, cap / p.name)
    (cap / "ip_fragments.pcap").write_bytes(fragment_seed())
    (cap / "wifi.pcap").write_bytes(wifi_seed())
    (cap / "wpa2.pcap").write_bytes(wpa_seed())
    (cap / "checksums.pcap").write_bytes(checksum_seed())
    for target, seeds in (("filter", [f.encode() for f in FILTERS]), ("keys", [k.encode() for k in KEY_SPECS]),
                          ("tcp", tcp_seeds()), ("analyses", analyses_seeds()),
                          ("export", export_seeds())):
        d = corpus / target
        d.mkdir(parents=True, exist_ok=True)
        for i, s in enumerate(seeds):
            (d / f"seed{i:03d}").write_bytes(s)
