"""Capture records: a scapy-built packet (or a hand-built SLL2 one) plus where its payload and its
MAVLink frames sit, so that expected.json can give each frame's file offset without decoding."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from random import Random

from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import Dot1Q, Ether
from scapy.packet import Packet as ScapyPacket
from scapy.packet import Raw

from .constants import ZERO_MAC
from .frames import Frame, Send


@dataclass
class Pkt:
    """One capture record, and the MAVLink content a decoder must find in it."""

    t_ns: int  # nanoseconds since the capture start
    data: bytes
    payload_at: int = 0  # offset of the UDP/TCP payload (or of the MAVLink bytes) in data
    frames: list[tuple[int, Frame]] = field(default_factory=list)  # (payload offset, frame) in order
    cuts: list[int] = field(default_factory=list)  # payload offsets of truncated frames (noted, not counted)
    skipped: int = 0  # bytes belonging to no frame
    iface: int = 0  # pcapng interface
    cut_to: int | None = None  # write only this many bytes of data (the file ends mid-record)


def wrap_packet(pkt: ScapyPacket, payload: bytes, t_us: int, frames: Sequence[Frame] = (), *,
          cuts: Sequence[int] = (), skipped: int = 0, frame_offsets: Sequence[int] | None = None) -> Pkt:
    """Build a scapy packet and remember where its payload and frames are."""
    data = bytes(pkt / Raw(payload)) if payload else bytes(pkt)
    offsets = list(frame_offsets) if frame_offsets is not None else stacked_offsets(frames)
    return Pkt(t_us * 1000, data, len(data) - len(payload), list(zip(offsets, frames)), list(cuts), skipped)


def stacked_offsets(frames: Sequence[Frame]) -> list[int]:
    """Offset of each frame in the frames written back to back."""
    out, pos = [], 0
    for fr in frames:
        out.append(pos)
        pos += len(fr.data)
    return out


class UdpFlow:
    """Two UDP endpoints on Ethernet (zero MACs: Linux loopback) with per-sender IP ids."""

    def __init__(self, addr: dict[str, tuple[str, int]], rng: Random,
                 macs: dict[str, str] | None = None, vlan: int | None = None) -> None:
        self.addr = addr
        self.macs = macs or {side: ZERO_MAC for side in addr}
        self.vlan = vlan
        self.ip_id = {side: rng.randint(1_000, 60_000) for side in addr}

    def packet(self, send: Send) -> Pkt:
        """One datagram from `send.side` to the other side, with that sender's next IP id."""
        src, dst = send.side, "gcs" if send.side == "vehicle" else "vehicle"
        self.ip_id[src] = (self.ip_id[src] + 1) % 65_536
        link = Ether(src=self.macs[src], dst=self.macs[dst])
        if self.vlan is not None:
            link = link / Dot1Q(vlan=self.vlan)
        ip = IP(src=self.addr[src][0], dst=self.addr[dst][0], id=self.ip_id[src], flags="DF", ttl=64)
        udp = UDP(sport=self.addr[src][1], dport=self.addr[dst][1])
        return wrap_packet(link / ip / udp, b"".join(f.data for f in send.frames), send.t_us, send.frames)
