"""The upper layers an IP packet's protocol number leads to (mavscope.transport.dispatch IP_PROTOCOLS): UDP, whose
destination port may lead on to a tunnel (UDP_PORTS), and TCP, whose segments go to reassembly."""

from __future__ import annotations

import struct

from mavscope.notes import Note, note
from mavscope.transport.base import TRANSPORT_TCP, TRANSPORT_UDP, Payload
from mavscope.transport.checksum import PROTO_TCP, PROTO_UDP, Checksum, judge
from mavscope.transport.packet import Decoded, Layers, Packet, Tunnel
from mavscope.transport.tcp import TCP_FIN, TCP_RST

_UDP = struct.Struct("!HHH")
_TCP = struct.Struct("!HHIIBB")  # ports, sequence and acknowledgment numbers, data offset byte, flags byte


def udp(layers: Layers, pkt: Packet) -> Decoded:
    """A UDP datagram's payload, or the packet inside it where a tunnel bound to its destination port finds one."""
    at, v4, _, src, dst, data, l4, end, whole, dropped, header_zero = pkt
    rec, base, span, _, outer, _ = at
    first = outer if dropped is None else (*outer, dropped)
    if l4 + 8 > end:
        return [], (*first, note("malformed-packet", f"UDP header cut short at byte {l4}{at.where()}", at.at(l4)))
    sport, dport, ulen = _UDP.unpack_from(data, l4)
    if ulen < 8:
        if ulen or v4:
            return [], (*first, note("malformed-packet", f"UDP length {ulen} < 8 at byte {l4}{at.where()}",
                                     at.at(l4)))
        ulen = end - l4  # IPv6 jumbogram
    stop = min(l4 + ulen, end)
    notes, placeholder = first, False
    if whole:
        more, placeholder = _udp_dropped(v4, src, dst, data, l4, ulen, end, at.where(), at.at(l4))
        notes += more
    bound = layers.udp_ports.get(dport)
    if isinstance(bound, Tunnel):  # (a receiver that drops the tunnel's datagram never reads what it carries)
        got = bound.decode(layers, at, data, l4 + 8, stop, notes, header_zero or placeholder)
        if got is not None:
            return got
    ep = layers.endpoints
    s = ep.v4_bytes(src, sport) if v4 else ep.v6(src, sport)
    d = ep.v4_bytes(dst, dport) if v4 else ep.v6(dst, dport)
    return [Payload(TRANSPORT_UDP, s, d, data[l4 + 8:stop], None, rec.number, None if base is None else base + l4 + 8,
                    (), span)], notes


def tcp(layers: Layers, pkt: Packet) -> Decoded:
    """A TCP segment to reassembly, unless a receiver drops it (mavscope.transport.checksum Directions.fate)."""
    at, v4, _, src, dst, data, l4, end, whole, dropped, header_zero = pkt
    rec, base, span, _, outer, _ = at
    if l4 + 20 > end:
        return [], (*pkt.first(), note("malformed-packet", f"TCP header cut short at byte {l4}{at.where()}",
                                       at.at(l4)))
    sport, dport, seq, ack, doff, flags = _TCP.unpack_from(data, l4)
    hlen = (doff >> 4) * 4
    if hlen < 20 or l4 + hlen > end:
        return [], (*pkt.first(), note("malformed-packet", f"TCP header length {hlen} does not fit at byte "
                                       f"{l4}{at.where()}", at.at(l4)))
    ep = layers.endpoints
    s = ep.v4_bytes(src, sport) if v4 else ep.v6(src, sport)
    d = ep.v4_bytes(dst, dport) if v4 else ep.v6(dst, dport)
    if dropped is None and outer:
        dropped = note(outer[0].code, "carried in a tunnel packet that a receiver drops", outer[0].offset)
    verdict, field, right = (judge(not v4, src, dst, PROTO_TCP, data, l4, end) if whole and dropped is None
                             else (Checksum.ABSENT, 0, 0))
    header = None if base is None else base + l4  # the file offsets of the TCP header and of its payload
    body = None if header is None else header + hlen
    said, drop = layers.directions.fate((s, d), end - l4 - hlen, dropped, verdict, field, right, header_zero,
                                        header, span is not None)
    if said is None:
        if flags & (TCP_FIN | TCP_RST) and verdict is Checksum.RIGHT and not header_zero:
            layers.directions.forget((s, d))  # its connection ends: a new one on the 4-tuple starts unknown
        return layers.tcp.segment(s, d, seq, flags, data[l4 + hlen:end], rec.number, body, ack, rec.time), outer
    # the note is the record's, now (not one for the stream's next frame to carry)
    out = [Payload(TRANSPORT_TCP, s, d, b"", None, rec.number, header, (said,))]
    if not drop:  # (else the receiver dropped it: its flags and bytes change nothing)
        out += layers.tcp.segment(s, d, seq, flags, data[l4 + hlen:end], rec.number, body, ack, rec.time)
    return out, outer


def _udp_dropped(v4: bool, src: bytes, dst: bytes, data: bytes, l4: int, ulen: int, end: int, where: str,
                 offset: int | None) -> tuple[tuple[Note, ...], bool]:
    """The notes on a whole UDP datagram at data[l4:end] that a receiver drops: a length past the packet's
    end (Linux: a short packet), a wrong checksum (not a sender's offload placeholder); and whether its
    checksum is such a placeholder (what a tunnel's datagram carries is judged with it)."""
    if l4 + ulen > end:
        return (note("malformed-packet", f"UDP length {ulen} runs past the end of its IP packet ({end - l4} bytes) "
                     f"at byte {l4}{where}: a receiver drops it (a short packet)", offset),), False
    verdict, field, right = judge(not v4, src, dst, PROTO_UDP, data, l4, l4 + ulen)
    if verdict is not Checksum.WRONG:
        return (), verdict is Checksum.OFFLOAD
    what = (f"UDP checksum 0 over IPv6, which requires one (RFC 8200 8.1; 0x{right:04x} is right)" if field == 0 else
            f"UDP checksum 0x{field:04x} is wrong (0x{right:04x} is right)")
    return (note("udp-bad-checksum", f"{what}{where}: a receiver that checks (Linux, and most IP stacks) drops this "
                 "datagram; its frames are shown", offset),), False
