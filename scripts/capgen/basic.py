"""The basic sessions: PX4 SITL over UDP (and the same frames as a QGC tlog and as a raw serial
stream), a MAVLink v1 session, a signed session, and a two-interface pcapng. Together they cover every
file format and link type mavscope reads."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path
from random import Random
from typing import Any

import pymavlink.dialects.v10.common as mav1
import pymavlink.dialects.v20.common as mav2
from scapy.layers.inet import IP, UDP
from scapy.layers.inet6 import IPv6
from scapy.layers.l2 import ARP, Ether
from scapy.packet import Raw

from .constants import (
    GCS_UDP_PORT,
    LINKTYPE_ETHERNET,
    LINKTYPE_LINUX_SLL2,
    LOOPBACK_V4,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_AUTOPILOT_PX4,
    VEHICLE_UDP_PORT,
    ZERO_MAC,
)
from .frames import Send, assert_no_stx, frame_crc_ok
from .packets import Pkt, UdpFlow, stacked_offsets, wrap_packet
from .story import PX4_UDP_STORY, Keyframe, Story
from .summary import summarize, summarize_packets
from .telemetry import PX4_STREAMS, Profile, build_session
from .writers import write_pcap, write_pcapng, write_tlog


def noise_packets(t_us: int, rng: Random) -> list[Pkt]:
    """Non-MAVLink traffic a decoder must ignore: an ARP request and a DNS query to port 53."""
    arp = Ether(src="02:42:ac:11:00:02", dst="ff:ff:ff:ff:ff:ff") / ARP(
        op=1, hwsrc="02:42:ac:11:00:02", psrc="172.17.0.2", hwdst=ZERO_MAC, pdst="172.17.0.1")
    # DNS query "px4.io A" by hand: header (id, RD, one question), name, QTYPE A, QCLASS IN.
    dns = struct.pack(">HHHHHH", rng.randint(0, 65_535), 0x0100, 1, 0, 0, 0) + b"\x03px4\x02io\x00" \
        + struct.pack(">HH", 1, 1)
    query = (Ether(src=ZERO_MAC, dst=ZERO_MAC)
             / IP(src=LOOPBACK_V4, dst="127.0.0.53", id=rng.randint(1, 65_535), flags="DF", ttl=64)
             / UDP(sport=rng.randint(32_768, 60_999), dport=53))
    return [wrap_packet(arp, b"", t_us), wrap_packet(query, dns, t_us + 40_000)]


def px4_sitl_udp(outdir: Path) -> tuple[dict[str, Any], list[Send]]:
    """The 60 s PX4 SITL session over UDP, with ARP and DNS noise; also returns its sends, which the tlog
    and the serial dump reuse."""
    rng = Random(1)
    profile = Profile(mav2, MAV_AUTOPILOT_PX4, PX4_STREAMS)
    sends = build_session(profile, PX4_UDP_STORY, rng)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    noise = noise_packets(12_345_678, rng) + noise_packets(47_654_321, rng)
    pkts = sorted(pkts + noise, key=lambda p: p.t_ns)  # stable: equal times keep their order
    offsets = write_pcap(outdir / "px4_sitl_udp.pcap", LINKTYPE_ETHERNET, pkts)
    summary = summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)
    summary["events"] = {"noise_records": [pkts.index(p) + 1 for p in noise]}
    return summary, sends


def px4_sitl_tlog(outdir: Path, sends: Sequence[Send]) -> dict[str, Any]:
    """QGroundControl tlog: each vehicle frame of the first 30 s of the UDP session."""
    timed = [(send.t_us, fr) for send in sends if send.side == "vehicle" and send.t_us < 30_000_000
             for fr in send.frames]
    offsets = write_tlog(outdir / "px4_sitl.tlog", [(t_us, fr.data) for t_us, fr in timed])
    located = [(n, 1, off, fr) for n, (off, (_, fr)) in enumerate(zip(offsets, timed), start=1)]
    return summarize("tlog", [], len(located), located, [], 0)


def serial_dump(outdir: Path, sends: Sequence[Send]) -> dict[str, Any]:
    """A raw serial stream: 10 s of vehicle frames, garbage between some, one frame cut short."""
    frames = [fr for s in sends if s.side == "vehicle" and s.t_us < 10_000_000 for fr in s.frames]
    garbage = {25: b"\x00", 80: b"\x55\xaa\x55", 150: b"\r\n", 190: b"\x00\x00\x00\x00\x07"}
    cut_index, cut_len = 110, 0
    while True:  # the first frame from #110 whose first 16 bytes hold no second start byte
        head = frames[cut_index].data[:16]
        if b"\xfd" not in head[1:] and b"\xfe" not in head[1:]:
            cut_len = 16
            break
        cut_index += 1
    out, located, skipped, cut_at = bytearray(), [], 0, 0
    for i, fr in enumerate(frames):
        if i in garbage:
            assert_no_stx(garbage[i], "serial garbage")
            out += garbage[i]
            skipped += len(garbage[i])
        if i == cut_index:
            cut_at = len(out)
            out += fr.data[:cut_len]
            # A decoder that took the next frame's bytes as this one's tail must see a bad CRC.
            assert not frame_crc_ok(fr.data[:cut_len] + frames[i + 1].data + frames[i + 2].data)
            continue
        located.append((None, len(located) + 1, len(out), fr))
        out += fr.data
    (outdir / "serial_dump.raw").write_bytes(bytes(out))
    return summarize("raw", [], None, located, [(None, cut_at)], skipped)


def mavlink_v1_udp(outdir: Path) -> dict[str, Any]:
    """An ArduCopter-style MAVLink v1 session: one frame per datagram, arm and its ACK."""
    rng = Random(3)
    story = Story(duration=20.0, keyframes=(Keyframe(0, 0, 0, 0, 0), Keyframe(20, 0, 0, 0, 0)), arm_at=8.0)
    profile = Profile(mav1, MAV_AUTOPILOT_ARDUPILOTMEGA, ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GPS_RAW_INT"),
                      bundle_p=0.0)
    sends = build_session(profile, story, rng)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    offsets = write_pcap(outdir / "mavlink_v1_udp.pcap", LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)


def signed_udp(outdir: Path) -> dict[str, Any]:
    """Every frame signed by pymavlink (vehicle link 0, GCS link 1): arm and RTL with their ACKs."""
    rng = Random(4)
    story = Story(duration=20.0, keyframes=(Keyframe(0, 0, 0, 0, 0), Keyframe(5, 0, 0, 0, 0),
                                            Keyframe(8, 0, 0, 15, 0), Keyframe(13, 30, 0, 15, 0),
                                            Keyframe(19, 0, 0, 15, 180), Keyframe(20, 0, 0, 12, 180)),
                  arm_at=4.0, rtl_at=13.0)
    profile = Profile(mav2, MAV_AUTOPILOT_PX4, ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT"),
                      signed=True)
    sends = build_session(profile, story, rng)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    offsets = write_pcap(outdir / "signed_udp.pcap", LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)


def px4_sitl_sll2(outdir: Path) -> dict[str, Any]:
    """pcapng, two interfaces: SLL2 + IPv6 loopback (µs), Ethernet + 802.1Q VLAN + IPv4 (ns)."""
    rng = Random(6)
    story = Story(duration=10.0, keyframes=(Keyframe(0, 0, 0, 10, 0), Keyframe(10, 30, 0, 10, 0)))
    streams = ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT")
    pkts: list[Pkt] = []

    # Interface 0: `tcpdump -i any` on Linux (SLL2) sees the SITL vehicle talk to QGC over [::1].
    flow_label = rng.getrandbits(20)
    for send in build_session(Profile(mav2, MAV_AUTOPILOT_PX4, streams), story, rng):
        sport, dport = (VEHICLE_UDP_PORT, GCS_UDP_PORT) if send.side == "vehicle" else (GCS_UDP_PORT, VEHICLE_UDP_PORT)
        payload = b"".join(f.data for f in send.frames)
        ip6 = bytes(IPv6(src="::1", dst="::1", hlim=64, fl=flow_label) / UDP(sport=sport, dport=dport) / Raw(payload))
        # SLL2: protocol, reserved, ifindex (1 = lo), ARPHRD_LOOPBACK, PACKET_HOST, addr len, addr (8)
        sll2 = struct.pack(">HHIHBB8s", 0x86DD, 0, 1, 772, 0, 6, b"")
        pkts.append(Pkt(send.t_us * 1000, sll2 + ip6, len(sll2) + len(ip6) - len(payload),
                        list(zip(stacked_offsets(send.frames), send.frames)), iface=0))

    # Interface 1: a second vehicle (sysid 2) on a lab network, VLAN 10, timestamps in nanoseconds.
    flow = UdpFlow({"vehicle": ("192.168.10.2", 14555), "gcs": ("192.168.10.1", GCS_UDP_PORT)}, rng,
                   macs={"vehicle": "02:00:00:0a:00:02", "gcs": "02:00:00:0a:00:01"}, vlan=10)
    for send in build_session(Profile(mav2, MAV_AUTOPILOT_PX4, streams, vehicle_sysid=2), story, rng):
        pkt = flow.packet(send)
        pkt.t_ns += rng.randint(0, 999)
        pkt.iface = 1
        pkts.append(pkt)

    pkts.sort(key=lambda p: p.t_ns)
    interfaces = [(LINKTYPE_LINUX_SLL2, "any", 6), (LINKTYPE_ETHERNET, "eth0", 9)]
    offsets = write_pcapng(outdir / "px4_sitl_sll2.pcapng", interfaces, pkts)
    return summarize_packets("pcapng", [LINKTYPE_LINUX_SLL2, LINKTYPE_ETHERNET], pkts, offsets)
