"""The Decapsulator: Records in, MAVLink-bearing Payloads out (UDP datagrams, reassembled TCP, tlog, raw)."""

from __future__ import annotations

import struct

from mavscope.capture.base import LINKTYPE_ETHERNET, LINKTYPE_MAVLINK_RAW, LINKTYPE_MAVLINK_TLOG, Record
from mavscope.endpoint import Endpoint
from mavscope.notes import GivenUp, Note, note
from mavscope.transport.air import Air
from mavscope.transport.base import TRANSPORT_RAW, TRANSPORT_TCP, TRANSPORT_TLOG, TRANSPORT_UDP, Payload
from mavscope.transport.checksum import FRAME_IP, Checksum, Directions, ipv4_header, judge, ones_sum
from mavscope.transport.defrag import Defragmenter, records_text
from mavscope.transport.ip import (
    PROTO_TCP,
    PROTO_UDP,
    Endpoints,
    FragmentInfo,
    options_problem,
    parse_ipv4,
    parse_ipv6,
    walk_ipv6,
)
from mavscope.transport.link import ETHERTYPE_IPV4, ETHERTYPE_IPV6, LinkResult, Subframes, Undecoded, strip_link
from mavscope.transport.tcp import MAX_BUFFERED, TCP_FIN, TCP_RST, TcpReassembler
from mavscope.transport.tunnel import MAX_DEPTH, PROTO_GRE, TUNNEL_PROTOS, VXLAN_PORTS, gre, ip_in_ip, vxlan
from mavscope.transport.wifi import Rebuilt
from mavscope.transport.wpa import Wpa

RAW_STREAM = (TRANSPORT_RAW,)  # the stream key of a raw byte-stream capture

# Ethernet + IPv4 + UDP in one go: (ethertype, version/IHL, TOS), IPv4 total length,
# (flags/fragment offset, TTL, protocol), UDP length
_FAST = struct.Struct("!12xIHxxI14xH")
_FAST_ETH_IP4 = 0x08004500  # ethertype IPv4, version 4, header length 20 (TOS masked off)
_FAST_UDP_UNFRAGMENTED = 17  # no MF flag, fragment offset 0, protocol UDP (TTL masked off)
_FLOW = struct.Struct("!IIHH")
_UDP = struct.Struct("!HHH")
REBUILT_KEPT = 65536  # records of rebuilt 802.11 frames remembered (for the IP datagrams they complete)
FLOW_CACHE = 16384  # (addresses, ports) -> names entries kept before the cache starts over
_TCP = struct.Struct("!HHIIBB")  # ports, sequence and acknowledgment numbers, data offset byte, flags byte

_tuple_new = tuple.__new__


class Decapsulator:
    """Strips link, IP, UDP and TCP headers from Records, keeping TCP reassembly state between them.

    `feed` returns the Payloads a record yields (UDP: at most one; TCP: the in-order pieces it makes
    deliverable); `flush` returns what TCP buffering still holds at the end of the capture. Record notes
    are carried on the first Payload produced from their record, or on an empty-data Payload.
    """

    def __init__(self, max_tcp_buffer: int = MAX_BUFFERED, wpa: Wpa | None = None) -> None:
        self.endpoints = Endpoints()
        self.air = Air(wpa)  # 802.11: duplicate detection, relays, fragments, WPA2 keys (--wifi-key)
        self.said = self.air.said  # what the bounds gave up (`capacity` notes), for the record being read
        self.tcp = TcpReassembler(max_tcp_buffer)
        self.defrag = Defragmenter(said=self.said)
        self._unknown_seen: set[int] = set()
        self._flows: dict[bytes, tuple[Endpoint, Endpoint]] = {}
        self.directions = Directions(said=self.said)  # the TCP directions whose captured checksums are real
        self.rebuilt: dict[int, tuple[int, ...]] = {}  # record -> the records its rebuilt 802.11 frame came from
        self.rebuilt_given_up = GivenUp(f"records of rebuilt 802.11 frames (at most {REBUILT_KEPT:,} remembered)",
                                        "records", self.said)

    def feed(self, rec: Record) -> list[Payload]:
        """The Payloads that `rec` yields now (possibly none)."""
        number, _, linktype, data, offset, _, notes = rec
        n = len(data)
        if linktype == LINKTYPE_ETHERNET and n >= 42 and not notes:
            # fast path: Ethernet + IPv4 without options + UDP, unfragmented, lengths consistent
            eth_ip, total, frag_proto, ulen = _FAST.unpack_from(data)
            if ((eth_ip & 0xFFFFFF00) == _FAST_ETH_IP4 and (frag_proto & 0x3FFF00FF) == _FAST_UDP_UNFRAGMENTED
                    and 28 <= total <= n - 14 and 8 <= ulen <= total - 20):
                flow = data[26:38]  # addresses and ports
                names = self._flows.get(flow)
                if names is None:
                    names = self._flow_names(flow)
                if names[1].port in VXLAN_PORTS:  # a tunnel's: the general path decodes what it carries
                    return self._slow(rec)
                if (data[24] or data[25]) and ones_sum(data, 14, 34):
                    return self._slow(rec)  # a wrong IPv4 header checksum: noted there
                # (the addresses, bytes 26-33, lie just before the datagram: with the protocol and the length
                # they are its pseudo-header)
                if (data[40] or data[41]) and (ones_sum(data, 26, 34 + ulen) + PROTO_UDP + ulen) % 0xFFFF and judge(
                        False, data[26:30], data[30:34], PROTO_UDP, data, 34, 34 + ulen)[0] is Checksum.WRONG:
                    return self._slow(rec)  # noted there
                return [_tuple_new(Payload, (TRANSPORT_UDP, names[0], names[1], data[42:34 + ulen], None,
                                             number, offset + 42, (), None, None))]
        return self._slow(rec)

    def _flow_names(self, flow: bytes) -> tuple[Endpoint, Endpoint]:
        """The source and destination Endpoints of the 12 bytes source address, destination address, ports."""
        src, dst, sport, dport = _FLOW.unpack(flow)
        names = (self.endpoints.v4(src, sport), self.endpoints.v4(dst, dport))
        if len(self._flows) >= FLOW_CACHE:
            self._flows.clear()
        self._flows[flow] = names
        return names

    def flush(self) -> list[Payload]:
        """End of capture: deliver the TCP bytes still buffered, with notes for the gaps skipped, and note
        the IP datagrams whose fragments never all came."""
        out = self.tcp.flush()
        out.extend(Payload(TRANSPORT_UDP, None, None, b"", None, record, None, (n,))
                   for record, n in self.defrag.flush())
        out.extend(Payload(TRANSPORT_UDP, None, None, b"", None, record, None, (note("wifi-fragment", m, None),))
                   for record, m in self.air.fragments.flush())
        return out

    def _slow(self, rec: Record) -> list[Payload]:
        number, _, linktype, data, roff, _, rnotes = rec
        if linktype == LINKTYPE_MAVLINK_TLOG:
            return [Payload(TRANSPORT_TLOG, None, None, data, None, number, roff, rnotes)]
        if linktype == LINKTYPE_MAVLINK_RAW:
            return [Payload(TRANSPORT_RAW, None, None, data, RAW_STREAM, number, roff, rnotes)]
        # a record the reader made only to carry its note (a block cut short): no packet to decode, so no
        # second note saying the packet is too short for its link header
        out, notes = ([], ()) if rnotes and not data else self._decode(rec)
        notes = rnotes + notes
        if self.said:
            notes += tuple(self.said)
            self.said.clear()
        if notes:
            if out:
                out[0] = out[0]._replace(notes=notes + out[0].notes)
            else:
                out.append(Payload(TRANSPORT_UDP, None, None, b"", None, number, roff, notes))
        return out

    def _decode(self, rec: Record) -> tuple[list[Payload], tuple[Note, ...]]:
        """Payloads and notes of one packet record (the slow, general path)."""
        _, _, linktype, data, roff, _, _ = rec
        self.air.record, self.air.time = rec.number, rec.time
        link = strip_link(linktype, data, self.air, rec.orig_len <= len(data))
        if isinstance(link, Rebuilt):  # a Wi-Fi frame decrypted or reassembled: bytes not in the file as such
            out, notes = self._link(rec, link.data, link.link, None)
            if link.records:  # its handshake's and fragments' records go with its frames (`read -w` writes them)
                out = [p._replace(span=self._also(tuple(sorted({*link.records, *(p.span or (rec.number,))}))))
                       for p in out]
                if not out:  # (an IP fragment held, say: the record that completes its datagram names these)
                    self._remember(rec.number, link.records)
            dropped = tuple(note("wifi-fragment", m, roff) for m in link.dropped)
            return out, dropped + notes
        return self._link(rec, data, link, roff)

    def _remember(self, record: int, others: tuple[int, ...]) -> None:
        """The other records a rebuilt 802.11 frame of `record` came from, for a datagram that record
        completes later (its IP fragment, reassembled in another record)."""
        self.rebuilt[record] = others
        if len(self.rebuilt) > REBUILT_KEPT:
            gone = next(iter(self.rebuilt))
            self.rebuilt_given_up.add(f"forgot the other records of record {gone}'s 802.11 frame, so a datagram it "
                                      "completes later is written (read -w) without them", len(self.rebuilt[gone]))
            del self.rebuilt[gone]

    def _also(self, span: tuple[int, ...]) -> tuple[int, ...]:
        """`span` with the records each of its rebuilt 802.11 frames came from."""
        more = {r for s in span for r in self.rebuilt.get(s, ())}
        return tuple(sorted({*span, *more})) if more else span

    def _link(self, rec: Record, data: bytes, link: LinkResult, base: int | None,
              ) -> tuple[list[Payload], tuple[Note, ...]]:
        """The payloads and notes of a packet record whose link layer `link` is (`data`: its bytes, or a
        decrypted frame's; `base`: the file offset of data[0], None for a decrypted frame)."""
        linktype, roff = rec.linktype, rec.offset
        if isinstance(link, Rebuilt):
            link = "802.11 frame rebuilt twice"
        if link is None:
            if linktype in self._unknown_seen:
                return [], ()
            self._unknown_seen.add(linktype)
            return [], (note("unknown-linktype", f"link type {linktype} is not decoded", roff),)
        if isinstance(link, str):
            return [], (note("malformed-packet", f"{link}", roff),)
        if isinstance(link, Undecoded):
            return [], (note(link.code, link.message, roff),)
        if isinstance(link, Subframes):  # several packets in one record: each decoded as a packet
            out: list[Payload] = []
            notes: tuple[Note, ...] = ()
            for et, off, end in link.packets:
                got, more = self._network(rec, data, et, off, base, limit=end)
                out += got
                notes += more
            if link.problem is not None:
                notes += (note("malformed-packet", link.problem, roff),)
            return out, notes
        return self._network(rec, data, *link, base)

    def _network(self, rec: Record, data: bytes, et: int, off: int, base: int | None,
                 span: tuple[int, ...] | None = None, depth: int = 0, limit: int | None = None,
                 outer: tuple[Note, ...] = (), outer_zero: bool = False) -> tuple[list[Payload], tuple[Note, ...]]:
        """The IP packet at `off` in `data` (the record's bytes, or a reassembled datagram: `span`), ending by
        `limit` where given; `base` is the file offset of data[0] (None in a reassembled one), `depth` how many
        tunnels it is inside, `outer` the notes on the tunnel packet that carries it, a receiver drops (so this
        one with it), which come first, `outer_zero` whether that packet's checksum was a sender's placeholder."""
        if et == ETHERTYPE_IPV4:
            ip = parse_ipv4(data, off, limit)
        elif et == ETHERTYPE_IPV6:
            ip = parse_ipv6(data, off, limit)
        else:
            return [], outer
        if isinstance(ip, str):
            return [], (*outer, note("malformed-packet", f"{ip} (packet byte {off})", _at(base, off)))
        proto, src, dst, l4, end, fragment = ip
        v4 = et == ETHERTYPE_IPV4
        verdict, field, right = ipv4_header(data, off, l4 - off) if v4 else (Checksum.RIGHT, 0, 0)
        dropped = None
        what = "fragment before reassembly" if fragment is not None else "packet before UDP or TCP reads it"
        if verdict is Checksum.WRONG:
            dropped = note("ip-bad-checksum", f"IPv4 header checksum 0x{field:04x} is wrong (0x{right:04x} is "
                           f"right): a receiver drops this {what}", _at(base, off))
        elif v4 and l4 - off > 20:
            problem = options_problem(data, off + 20, l4)
            if problem is not None:
                dropped = note("malformed-packet", f"{problem}: a receiver drops this {what}", _at(base, off + 20))
        # the packet is all here, as long as its header says (unless the capture snapped it); else, where the
        # record is whole, its header lies and a receiver drops it
        size = (data[off + 2] << 8 | data[off + 3]) if v4 else (data[off + 4] << 8 | data[off + 5]) + 40
        whole = size > (0 if v4 else 40) and off + size == end
        if not whole and dropped is None and rec.orig_len <= len(rec.data):
            dropped = _length_lies(v4, size, end - off, _at(base, off))
        zero = outer_zero or (v4 and verdict is Checksum.OFFLOAD)
        if fragment is not None:
            if dropped is not None or outer:  # never reaches reassembly
                return [], (*outer, *(() if dropped is None else (dropped,)))
            return self._fragment(fragment._replace(header_zero=zero), proto, src, dst, data[l4:end], rec,
                                  _at(base, l4), depth)
        return self._layer4(v4, proto, src, dst, data, l4, end, rec, base, span, depth, whole, dropped, zero, outer)

    def _fragment(self, frag: FragmentInfo, proto: int, src: bytes, dst: bytes, data: bytes, rec: Record,
                  offset: int | None, depth: int) -> tuple[list[Payload], tuple[Note, ...]]:
        """An IP fragment to the reassembler; the datagram it completes, decoded as one packet."""
        whole, notes = self.defrag.add(frag, proto, src, dst, data, rec.number, rec.time, offset)
        if whole is None:
            return [], tuple(notes)
        buf, proto, l4 = whole.data, whole.proto, 0
        if frag.v6:  # the fragmentable part may start with extension headers before the upper layer
            walked = walk_ipv6(buf, 0, len(buf), proto)
            if isinstance(walked, str) or walked[2] is not None:
                why = walked if isinstance(walked, str) else "a fragment inside it, not reassembled again"
                return [], (*notes, note("malformed-packet", f"reassembled from {records_text(whole.records)}: {why}",
                                         None))
            proto, l4, _ = walked
        out, more = self._layer4(not frag.v6, proto, src, dst, buf, l4, len(buf), rec, None, self._also(whole.records),
                                 depth, True, header_zero=whole.header_zero)
        return out, (*notes, *more)

    def _layer4(self, v4: bool, proto: int, src: bytes, dst: bytes, data: bytes, l4: int, end: int, rec: Record,
                base: int | None, span: tuple[int, ...] | None, depth: int, whole: bool,
                dropped: Note | None = None, header_zero: bool = False,
                outer: tuple[Note, ...] = ()) -> tuple[list[Payload], tuple[Note, ...]]:
        """The UDP or TCP payload at data[l4:end], or the packet a tunnel carries there (`base`: the file offset
        of data[0], None for a datagram reassembled from the fragments of the records in `span`; `whole`: the
        IP packet ends at `end` as its header says, so its checksum can be judged; `dropped`: the note on an IP
        header a receiver drops the packet for; `header_zero`: an IPv4 header checksum of 0; `outer`: the notes
        on a tunnel packet a receiver drops, which carries this one)."""
        ep = self.endpoints
        number = rec.number
        where = f" (reassembled from {records_text(span)})" if span is not None else ""
        first = outer if dropped is None else (*outer, dropped)
        if proto == PROTO_UDP:
            if l4 + 8 > end:
                return [], (*first, note("malformed-packet", f"UDP header cut short at byte {l4}{where}",
                                         _at(base, l4)))
            sport, dport, ulen = _UDP.unpack_from(data, l4)
            if ulen < 8:
                if ulen or v4:
                    return [], (*first, note("malformed-packet", f"UDP length {ulen} < 8 at byte {l4}{where}",
                                             _at(base, l4)))
                ulen = end - l4  # IPv6 jumbogram
            stop = min(l4 + ulen, end)
            notes, placeholder = first, False
            if whole:
                more, placeholder = _udp_dropped(v4, src, dst, data, l4, ulen, end, where, _at(base, l4))
                notes += more
            if dport in VXLAN_PORTS:
                inner = vxlan(data, l4 + 8, stop)
                if inner is not None:  # (a receiver that drops the tunnel's datagram never reads what it carries)
                    return self._inner(rec, data[:stop], inner, base, span, depth, "VXLAN", notes,
                                       header_zero or placeholder)
            s = ep.v4_bytes(src, sport) if v4 else ep.v6(src, sport)
            d = ep.v4_bytes(dst, dport) if v4 else ep.v6(dst, dport)
            return [Payload(TRANSPORT_UDP, s, d, data[l4 + 8:stop], None, number, _at(base, l4 + 8), (), span)], notes
        if proto == PROTO_TCP:
            if l4 + 20 > end:
                return [], (*first, note("malformed-packet", f"TCP header cut short at byte {l4}{where}",
                                         _at(base, l4)))
            sport, dport, seq, ack, doff, flags = _TCP.unpack_from(data, l4)
            hlen = (doff >> 4) * 4
            if hlen < 20 or l4 + hlen > end:
                return [], (*first, note("malformed-packet", f"TCP header length {hlen} does not fit at byte "
                                         f"{l4}{where}", _at(base, l4)))
            s = ep.v4_bytes(src, sport) if v4 else ep.v6(src, sport)
            d = ep.v4_bytes(dst, dport) if v4 else ep.v6(dst, dport)
            if dropped is None and outer:
                dropped = note(outer[0].code, "carried in a tunnel packet that a receiver drops", outer[0].offset)
            verdict, field, right = (judge(not v4, src, dst, PROTO_TCP, data, l4, end) if whole and dropped is None
                                     else (Checksum.ABSENT, 0, 0))
            said, drop = self.directions.fate((s, d), end - l4 - hlen, dropped, verdict, field, right, header_zero,
                                              _at(base, l4), span is not None)
            if said is None:
                if flags & (TCP_FIN | TCP_RST) and verdict is Checksum.RIGHT and not header_zero:
                    self.directions.forget((s, d))  # its connection ends: a new one on the 4-tuple starts unknown
                return self.tcp.segment(s, d, seq, flags, data[l4 + hlen:end], number, _at(base, l4 + hlen), ack,
                                        rec.time), outer
            # the note is the record's, now (not one for the stream's next frame to carry)
            out = [Payload(TRANSPORT_TCP, s, d, b"", None, number, _at(base, l4), (said,))]
            if not drop:  # (else the receiver dropped it: its flags and bytes change nothing)
                out += self.tcp.segment(s, d, seq, flags, data[l4 + hlen:end], number, _at(base, l4 + hlen), ack,
                                        rec.time)
            return out, outer
        if proto in TUNNEL_PROTOS:
            inner = gre(data, l4, end) if proto == PROTO_GRE else ip_in_ip(proto, l4)
            return self._inner(rec, data[:end], inner, base, span, depth, "GRE" if proto == PROTO_GRE else "IP-in-IP",
                               first, header_zero)
        return [], first

    def _inner(self, rec: Record, data: bytes, inner: tuple[int, int] | str, base: int | None,
               span: tuple[int, ...] | None, depth: int, kind: str, outer: tuple[Note, ...],
               outer_zero: bool) -> tuple[list[Payload], tuple[Note, ...]]:
        """The packet a tunnel carries (`inner`: its ethertype and offset in `data`, or what is wrong; `outer`:
        the notes on the tunnel's packet, which a receiver drops, that come first; `outer_zero`: its checksum
        was a sender's placeholder)."""
        if isinstance(inner, str):
            return [], (*outer, note("malformed-packet", f"{kind}: {inner}", base))
        if depth >= MAX_DEPTH:
            return [], (*outer, note("malformed-packet", f"{kind} tunnel inside {MAX_DEPTH} others: not decoded",
                                     base))
        return self._network(rec, data, *inner, base, span, depth + 1, outer=outer, outer_zero=outer_zero)


def _length_lies(v4: bool, size: int, have: int, offset: int | None) -> Note | None:
    """The note on an IP packet, not snapped, whose header's length (`size`, header included) disagrees with the
    `have` bytes there are: longer (Linux drops it as truncated), or 0 in a packet one Ethernet frame holds (a
    packet is given none only when a length cannot say it, BIG TCP's over 64 KiB, or by a sender for its
    NIC to cut: Windows' LSOv2)."""
    name = "IPv4 total length" if v4 else "IPv6 payload length"
    told = size if v4 else size - 40
    if size > (0 if v4 else 40):
        if size <= have:
            return None
        what = f"{name} {told} runs past the packet's {have} bytes"
    elif have > FRAME_IP:  # over 64 KiB (BIG TCP), or a sender's large send offload (Windows' LSOv2)
        return None
    else:
        what = f"{name} 0 in a packet of {have} bytes (only a packet larger than a frame is given no length)"
    return note("malformed-packet", f"{what}: a receiver drops it", offset)


def _udp_dropped(v4: bool, src: bytes, dst: bytes, data: bytes, l4: int, ulen: int, end: int, where: str,
                 offset: int | None) -> tuple[tuple[Note, ...], bool]:
    """The notes on a whole UDP datagram at data[l4:end] that a receiver drops: a length past the packet's
    end (Linux: a short packet), a wrong checksum (not a sender's offload placeholder); and whether its
    checksum is such a placeholder (what a VXLAN datagram carries is judged with it)."""
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


def _at(base: int | None, pos: int) -> int | None:
    """The file offset of byte `pos` of a packet whose byte 0 lies at `base` (None: not in the file as such)."""
    return None if base is None else base + pos
