"""What one step of the transport dispatch hands the next (mavscope.transport.dispatch): where a packet lies
(`Carrier`), an IP packet's upper layer (`Packet`), a tunnel (`Tunnel`), and the state the decoders share
(`Layers`: the Decapsulator).

Carrier and Packet are NamedTuples, as Payload and Record are: immutable records made for every packet on the
general path, where a frozen dataclass's construction (a checked setattr a field) cost 2 µs a packet, a fifth
of that path's time on a TCP capture."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple, Protocol

from mavscope.capture.base import Record
from mavscope.notes import Note, note
from mavscope.transport.base import Payload
from mavscope.transport.checksum import Directions
from mavscope.transport.defrag import records_text
from mavscope.transport.ip import Endpoints
from mavscope.transport.tcp import TcpReassembler
from mavscope.transport.tunnel import Inner

Decoded = tuple[list[Payload], tuple[Note, ...]]  # the Payloads of a packet and the notes on it


class Carrier(NamedTuple):
    """Where a network-layer packet lies: in record `rec`, at file offset `base` of its bytes' byte 0 (None: not
    in the file as such, a rebuilt 802.11 frame or a reassembled datagram), reassembled from the records in
    `span` (else None), inside `depth` tunnels; `outer`: the notes on the tunnel packet carrying it, which a
    receiver drops (so this one with it), that come first; `outer_zero`: that packet's checksum was a sender's
    placeholder (offload)."""

    rec: Record
    base: int | None
    span: tuple[int, ...] | None = None
    depth: int = 0
    outer: tuple[Note, ...] = ()
    outer_zero: bool = False

    def at(self, pos: int) -> int | None:
        """The file offset of byte `pos` of the packet's bytes (None: not in the file as such)."""
        return None if self.base is None else self.base + pos

    def where(self) -> str:
        """" (reassembled from records 1, 2)" for a reassembled datagram's notes, else ""."""
        return f" (reassembled from {records_text(self.span)})" if self.span is not None else ""


class Packet(NamedTuple):
    """An IP packet's upper layer, data[l4:end], as IP_PROTOCOLS' decoders get it: the IP header's protocol and
    addresses, `whole` (the packet ends at `end` as its header says, so a checksum can be judged), `dropped`
    (the note on an IP header a receiver drops the packet for), `header_zero` (an IPv4 header checksum of 0,
    left to the NIC, or such a tunnel packet's)."""

    at: Carrier
    v4: bool
    proto: int
    src: bytes
    dst: bytes
    data: bytes
    l4: int
    end: int
    whole: bool
    dropped: Note | None = None
    header_zero: bool = False

    def first(self) -> tuple[Note, ...]:
        """The notes that come before any this layer makes: the carrying tunnel's, then the IP header's."""
        outer = self.at.outer
        return outer if self.dropped is None else (*outer, self.dropped)


class PortRole(Enum):
    """What a UDP port is bound to besides a tunnel."""

    MAVLINK = "mavlink"  # MAVLink's by convention: a datagram to or from it is scanned as MAVLink even unproven


class Layers(Protocol):
    """The Decapsulator's state the upper-layer decoders use, and its way back down for a tunnel's packet."""

    endpoints: Endpoints
    directions: Directions
    tcp: TcpReassembler
    udp_ports: dict[int, Tunnel | PortRole]

    def carried(self, at: Carrier, data: bytes, inner: tuple[int, int], kind: str, outer: tuple[Note, ...],
                outer_zero: bool) -> Decoded:
        """The packet a tunnel of `kind` carries at `inner` (ethertype, offset) in `data`."""
        ...


Upper = Callable[[Layers, Packet], Decoded]  # an IP protocol's decoder


@dataclass(frozen=True, slots=True)
class Tunnel:
    """A tunnel: `name` (for its notes) and `inner(data, start, end)`, the packet inside the tunnel header at
    data[start:end]: (its ethertype, or 0 for one that is not IP, and its offset), what is wrong (str), or None
    (not this tunnel after all: a datagram to a tunnel's UDP port is then read as any other). Bound to an IP
    protocol it is that protocol's decoder; bound to a UDP port, the datagrams to that port are tried."""

    name: str
    inner: Callable[[bytes, int, int], Inner]

    def __call__(self, layers: Layers, pkt: Packet) -> Decoded:
        """The packet this tunnel carries in an IP packet's payload."""
        return self.decode(layers, pkt.at, pkt.data, pkt.l4, pkt.end, pkt.first(), pkt.header_zero) or ([],
                                                                                                         pkt.first())

    def decode(self, layers: Layers, at: Carrier, data: bytes, start: int, end: int, outer: tuple[Note, ...],
               outer_zero: bool) -> Decoded | None:
        """What the tunnel header at data[start:end] carries, decoded (None: not this tunnel)."""
        inner = self.inner(data, start, end)
        if inner is None:
            return None
        if isinstance(inner, str):
            return [], (*outer, note("malformed-packet", f"{self.name}: {inner}", at.base))
        return layers.carried(at, data[:end], inner, self.name, outer, outer_zero)
