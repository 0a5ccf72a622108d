"""The Decapsulator: Records in, MAVLink-bearing Payloads out (UDP datagrams, reassembled TCP, tlog, raw)."""

from __future__ import annotations

import struct

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.endpoint import Endpoint
from mavscope.notes import GivenUp, Note, note
from mavscope.transport.air import Air
from mavscope.transport.base import TRANSPORT_UDP, Payload
from mavscope.transport.checksum import FRAME_IP, Checksum, Directions, ipv4_header, judge, ones_sum
from mavscope.transport.defrag import Defragmenter, records_text
from mavscope.transport.dispatch import TABLES, Tables
from mavscope.transport.ip import PROTO_UDP, Endpoints, FragmentInfo, options_problem, walk_ipv6
from mavscope.transport.link import LinkResult, Subframes, Undecoded
from mavscope.transport.packet import Carrier, Decoded, Packet
from mavscope.transport.tcp import MAX_BUFFERED, TcpReassembler
from mavscope.transport.tunnel import MAX_DEPTH
from mavscope.transport.wifi import Rebuilt
from mavscope.transport.wpa import Wpa

# Ethernet + IPv4 + UDP in one go: (ethertype, version/IHL, TOS), IPv4 total length,
# (flags/fragment offset, TTL, protocol), UDP length
_FAST = struct.Struct("!12xIHxxI14xH")
_FAST_ETH_IP4 = 0x08004500  # ethertype IPv4, version 4, header length 20 (TOS masked off)
_FAST_UDP_UNFRAGMENTED = 17  # no MF flag, fragment offset 0, protocol UDP (TTL masked off)
_FLOW = struct.Struct("!IIHH")
REBUILT_KEPT = 65536  # records of rebuilt 802.11 frames remembered (for the IP datagrams they complete)
FLOW_CACHE = 16384  # (addresses, ports) -> names entries kept before the cache starts over

_tuple_new = tuple.__new__


class Decapsulator:
    """Strips link, IP, UDP and TCP headers from Records, keeping TCP reassembly state between them.

    `feed` returns the Payloads a record yields (UDP: at most one; TCP: the in-order pieces it makes
    deliverable); `flush` returns what TCP buffering still holds at the end of the capture. Record notes
    are carried on the first Payload produced from their record, or on an empty-data Payload.
    """

    def __init__(self, max_tcp_buffer: int = MAX_BUFFERED, wpa: Wpa | None = None, tables: Tables = TABLES) -> None:
        """`tables`: the dispatch tables (mavscope.transport.dispatch), read now: what is bound later is not seen."""
        self.link_types = dict(tables.link_types)
        self.byte_link_types = dict(tables.byte_link_types)
        self.ethertypes = dict(tables.ethertypes)
        self.ip_protocols = dict(tables.ip_protocols)
        self.udp_ports = dict(tables.udp_ports)
        self.mavlink_ports = tables.mavlink_ports()  # (the dissector's: a datagram on one is taken for MAVLink)
        self._tunnel_ports = tables.tunnel_ports()
        if not tables.fast_path():  # Ethernet, IPv4 or UDP bound elsewhere: the general path reads every record
            self.feed = self._slow  # type: ignore[method-assign]
        self.endpoints = Endpoints()
        self.air = Air(wpa)  # 802.11: duplicate detection, relays, fragments, WPA2 keys (--wifi-key)
        self.said = self.air.said  # what the bounds gave up (`capacity` notes), for the record being read
        self.tcp = TcpReassembler(max_tcp_buffer)
        self.defrag = Defragmenter(said=self.said)
        self._unknown_seen: set[int] = set()
        self._flows: dict[bytes, tuple[Endpoint, Endpoint, bool]] = {}  # and whether a tunnel's port is the dst
        self.directions = Directions(said=self.said)  # the TCP directions whose captured checksums are real
        self.rebuilt: dict[int, tuple[int, ...]] = {}  # record -> the records its rebuilt 802.11 frame came from
        self.rebuilt_given_up = GivenUp(f"records of rebuilt 802.11 frames (at most {REBUILT_KEPT:,} remembered)",
                                        "records", self.said)

    def feed(self, rec: Record) -> list[Payload]:
        """The Payloads that `rec` yields now (possibly none)."""
        number, _, linktype, data, offset, _, notes = rec
        n = len(data)
        if linktype == LINKTYPE_ETHERNET and n >= 42 and not notes:
            # fast path: Ethernet + IPv4 without options + UDP, unfragmented, lengths consistent (the tables' own
            # Ethernet, IPv4 and UDP decoders, as __init__ checks)
            eth_ip, total, frag_proto, ulen = _FAST.unpack_from(data)
            if ((eth_ip & 0xFFFFFF00) == _FAST_ETH_IP4 and (frag_proto & 0x3FFF00FF) == _FAST_UDP_UNFRAGMENTED
                    and 28 <= total <= n - 14 and 8 <= ulen <= total - 20):
                flow = data[26:38]  # addresses and ports
                names = self._flows.get(flow)
                if names is None:
                    names = self._flow_names(flow)
                if names[2]:  # to a tunnel's port: the general path decodes what it carries
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

    def _flow_names(self, flow: bytes) -> tuple[Endpoint, Endpoint, bool]:
        """The source and destination Endpoints of the 12 bytes source address, destination address, ports, and
        whether a tunnel is bound to the destination port."""
        src, dst, sport, dport = _FLOW.unpack(flow)
        names = (self.endpoints.v4(src, sport), self.endpoints.v4(dst, dport), dport in self._tunnel_ports)
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
        byte_link = self.byte_link_types.get(linktype)
        if byte_link is not None:  # MAVLink bytes as they are (a tlog entry, a raw stream's chunk)
            return [Payload(byte_link.transport, None, None, data, byte_link.stream, number, roff, rnotes)]
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
        decode = self.link_types.get(linktype)
        link = None if decode is None else decode(data, self.air, rec.orig_len <= len(data))
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

    def _link(self, rec: Record, data: bytes, link: LinkResult, base: int | None) -> Decoded:
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
        at = Carrier(rec, base)
        if isinstance(link, Subframes):  # several packets in one record: each decoded as a packet
            out: list[Payload] = []
            notes: tuple[Note, ...] = ()
            for et, off, end in link.packets:
                got, more = self._network(at, data, et, off, limit=end)
                out += got
                notes += more
            if link.problem is not None:
                notes += (note("malformed-packet", link.problem, roff),)
            return out, notes
        return self._network(at, data, *link)

    def _network(self, at: Carrier, data: bytes, et: int, off: int, limit: int | None = None) -> Decoded:
        """The network-layer packet of ethertype `et` at `off` in `data` (the record's bytes, a rebuilt frame's, or
        a tunnel's packet), ending by `limit` where given; `at`: where it lies and what carries it."""
        version = self.ethertypes.get(et)
        outer = at.outer
        if version is None:
            return [], outer
        ip = version.parse(data, off, limit)
        if isinstance(ip, str):
            return [], (*outer, note("malformed-packet", f"{ip} (packet byte {off})", at.at(off)))
        proto, src, dst, l4, end, fragment = ip
        v4 = version.v4
        verdict, field, right = ipv4_header(data, off, l4 - off) if v4 else (Checksum.RIGHT, 0, 0)
        dropped = None
        what = "fragment before reassembly" if fragment is not None else "packet before UDP or TCP reads it"
        if verdict is Checksum.WRONG:
            dropped = note("ip-bad-checksum", f"IPv4 header checksum 0x{field:04x} is wrong (0x{right:04x} is "
                           f"right): a receiver drops this {what}", at.at(off))
        elif v4 and l4 - off > 20:
            problem = options_problem(data, off + 20, l4)
            if problem is not None:
                dropped = note("malformed-packet", f"{problem}: a receiver drops this {what}", at.at(off + 20))
        # the packet is all here, as long as its header says (unless the capture snapped it); else, where the
        # record is whole, its header lies and a receiver drops it
        size = (data[off + 2] << 8 | data[off + 3]) if v4 else (data[off + 4] << 8 | data[off + 5]) + 40
        whole = size > (0 if v4 else 40) and off + size == end
        rec = at.rec
        if not whole and dropped is None and rec.orig_len <= len(rec.data):
            dropped = _length_lies(v4, size, end - off, at.at(off))
        zero = at.outer_zero or (v4 and verdict is Checksum.OFFLOAD)
        if fragment is not None:
            if dropped is not None or outer:  # never reaches reassembly
                return [], (*outer, *(() if dropped is None else (dropped,)))
            return self._fragment(fragment._replace(header_zero=zero), proto, src, dst, data[l4:end], rec,
                                  at.at(l4), at.depth)
        decode = self.ip_protocols.get(proto)  # (what _upper does, inline: every packet comes this way)
        if decode is None:
            return [], outer if dropped is None else (*outer, dropped)
        return decode(self, Packet(at, v4, proto, src, dst, data, l4, end, whole, dropped, zero))

    def _fragment(self, frag: FragmentInfo, proto: int, src: bytes, dst: bytes, data: bytes, rec: Record,
                  offset: int | None, depth: int) -> Decoded:
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
        at = Carrier(rec, None, self._also(whole.records), depth)
        out, more = self._upper(Packet(at, not frag.v6, proto, src, dst, buf, l4, len(buf), True,
                                       header_zero=whole.header_zero))
        return out, (*notes, *more)

    def _upper(self, pkt: Packet) -> Decoded:
        """The IP packet's upper layer, by its protocol (dispatch.IP_PROTOCOLS: UDP, TCP, tunnels)."""
        decode = self.ip_protocols.get(pkt.proto)
        if decode is None:
            return [], pkt.first()
        return decode(self, pkt)

    def carried(self, at: Carrier, data: bytes, inner: tuple[int, int], kind: str, outer: tuple[Note, ...],
                outer_zero: bool) -> Decoded:
        """The packet a tunnel of `kind` carries (`inner`: its ethertype and offset in `data`), in the packet at
        `at`; `outer`: the notes on the tunnel's packet, which a receiver drops, that come first; `outer_zero`: its
        checksum was a sender's placeholder."""
        if at.depth >= MAX_DEPTH:
            return [], (*outer, note("malformed-packet", f"{kind} tunnel inside {MAX_DEPTH} others: not decoded",
                                     at.base))
        return self._network(Carrier(at.rec, at.base, at.span, at.depth + 1, outer, outer_zero), data, *inner)


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
