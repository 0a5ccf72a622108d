"""MAVLink over TCP captures built with scapy, with segments the capture misses, for the reassembly tests.

A vehicle (10.0.0.1:5760) sends frames to a ground station (10.0.0.2:40000) after a handshake; the stream
is cut into segments (one frame each, or a fixed size), each sent at a time of its own. The capture may
miss segments, hold them out of order, and carry the ground station's ACKs (or not: a capture of one
direction). What each test expects is derived from this construction: which bytes were captured, in which
record, at which time, never from mavscope.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.l2 import Ether
from scapy.utils import wrpcap

from tests.support.flows import Sender, heartbeat

T0 = 1_700_000_000.0
VEHICLE = ("10.0.0.1", 5760)
GCS = ("10.0.0.2", 40000)
V_ISN, G_ISN = 999, 4999  # the first data bytes are 1000 (vehicle) and 5000 (ground station)
UDP_SRC, UDP_DST = ("10.0.0.3", 14550), ("10.0.0.4", 14550)  # another vehicle's link, over UDP (build's `udp`)


@dataclass(frozen=True, slots=True)
class Segment:
    """One data segment of the vehicle's stream: stream positions [start, end) from 0, sent at time `t`."""

    start: int
    data: bytes
    t: float

    @property
    def end(self) -> int:
        return self.start + len(self.data)

    @property
    def seq(self) -> int:
        return V_ISN + 1 + self.start


@dataclass(slots=True)
class Capture:
    """The packets written (in record order, records numbered from 1) and what each data segment became."""

    packets: list = field(default_factory=list)
    record_of: dict[int, int] = field(default_factory=dict)  # segment index -> its record (captured ones)
    ack_of: dict[int, int] = field(default_factory=dict)  # segment index -> the record of the ACK of its end
    udp_of: dict[int, int] = field(default_factory=dict)  # segment index -> the record of the datagram after it

    def add(self, src: tuple[str, int], dst: tuple[str, int], seq: int, ack: int, flags: str, t: float,
            data: bytes = b"") -> int:
        p = Ether(src="02:00:00:00:00:01", dst="02:00:00:00:00:02") / IP(src=src[0], dst=dst[0]) / TCP(
            sport=src[1], dport=dst[1], seq=seq % (1 << 32), ack=ack % (1 << 32), flags=flags) / data
        p.time = T0 + t
        self.packets.append(p)
        return len(self.packets)

    def datagram(self, payload: bytes, t: float) -> int:
        """A UDP datagram of another link (UDP_SRC -> UDP_DST) at time `t`; its record."""
        p = Ether(src="02:00:00:00:00:03", dst="02:00:00:00:00:04") / IP(src=UDP_SRC[0], dst=UDP_DST[0]) / UDP(
            sport=UDP_SRC[1], dport=UDP_DST[1]) / payload
        p.time = T0 + t
        self.packets.append(p)
        return len(self.packets)

    def write(self, path: Path) -> Path:
        wrpcap(str(path), self.packets)
        return path


def heartbeats(n: int) -> list[bytes]:
    """`n` HEARTBEATs of system 1/1, sequence numbers 0..n-1 (pymavlink's packing)."""
    s = Sender(1, 1)
    return [s.pack(heartbeat()) for _ in range(n)]


def one_per_segment(frames: list[bytes], period: float = 1.0) -> list[Segment]:
    """A segment per frame, frame i sent at i * period."""
    out, pos = [], 0
    for i, f in enumerate(frames):
        out.append(Segment(pos, f, i * period))
        pos += len(f)
    return out


def chunks(frames: list[bytes], size: int, period: float = 1.0) -> list[Segment]:
    """The frames' bytes cut into segments of `size` bytes, segment i sent at i * period."""
    stream = b"".join(frames)
    return [Segment(i, stream[i:i + size], i // size * period) for i in range(0, len(stream), size)]


def build(segments: list[Segment], missed: set[int] = frozenset(), order: list[int] | None = None,  # type: ignore[assignment]
          acks: bool = True, handshake: bool = True, fin: bool = False, ack_delay: float = 0.01,
          udp: list[bytes] | None = None) -> Capture:
    """The capture of `segments`, the ones in `missed` not captured (the receiver had them: its ACKs, when
    `acks`, say so, `ack_delay` after each segment), the rest in `order` (segment indices; default: as sent).
    With `udp`, the k-th segment in that order (captured or not) is followed, half a second after it, by a
    datagram carrying udp[k] on another link (`udp_of`)."""
    cap = Capture()
    if handshake:
        cap.add(GCS, VEHICLE, G_ISN, 0, "S", -0.3)
        cap.add(VEHICLE, GCS, V_ISN, G_ISN + 1, "SA", -0.2)
        cap.add(GCS, VEHICLE, G_ISN + 1, V_ISN + 1, "A", -0.1)
    for i in order if order is not None else range(len(segments)):
        s = segments[i]
        if i not in missed:
            cap.record_of[i] = cap.add(VEHICLE, GCS, s.seq, G_ISN + 1, "PA", s.t, s.data)
        if acks:
            cap.ack_of[i] = cap.add(GCS, VEHICLE, G_ISN + 1, s.seq + len(s.data), "A", s.t + ack_delay)
        if udp is not None and len(cap.udp_of) < len(udp):
            cap.udp_of[i] = cap.datagram(udp[len(cap.udp_of)], s.t + 0.5)
    if fin:
        last = segments[-1]
        cap.add(VEHICLE, GCS, last.seq + len(last.data), G_ISN + 1, "FA", last.t + 0.5)
    return cap
