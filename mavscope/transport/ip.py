"""IPv4 and IPv6 headers: where the UDP or TCP header lies, and the Endpoints of a packet."""

from __future__ import annotations

import socket
import struct
from typing import NamedTuple

from mavscope.endpoint import Endpoint
from mavscope.transport.checksum import PROTO_TCP as PROTO_TCP  # (the protocol numbers live with the checksums)
from mavscope.transport.checksum import PROTO_UDP as PROTO_UDP

# IPv6 extension headers walked on the way to UDP/TCP
EXT_HOPOPTS = 0
EXT_ROUTING = 43
EXT_FRAGMENT = 44
EXT_DSTOPTS = 60
_EXT_SKIPPABLE = frozenset((EXT_HOPOPTS, EXT_ROUTING, EXT_DSTOPTS))
MAX_EXT_HEADERS = 16

_IPV4 = struct.Struct("!BBHHHBBxx4s4s")  # vihl, tos, total length, id, flags+fragment offset, ttl, proto, src, dst
_IPV6 = struct.Struct("!IHBB16s16s")  # version/class/flow, payload length, next header, hop limit, src, dst
_FRAG6 = struct.Struct("!BxHI")



class FragmentInfo(NamedTuple):
    """Where an IP fragment's bytes go in its datagram (mavscope.transport.defrag reassembles them)."""

    v6: bool
    ident: int  # the Identification field (16 bits in IPv4, 32 in IPv6)
    offset: int  # in bytes
    more: bool  # the MF / M flag: fragments follow
    header_len: int  # IPv4: the header's length (with options); IPv6: the extension headers before it
    length: int  # the fragment's bytes as its header counts them (more than were captured in a snapped record)
    ecn: int = 0  # the ECN bits of its TOS / traffic class (Linux discards a datagram that mixes them badly)
    header_zero: bool = False  # IPv4: a header checksum of 0, not judged (a sender's NIC fills it in)

    def describe(self) -> str:
        more = " (more follow)" if self.more else ""
        return f"IPv{6 if self.v6 else 4} fragment id {self.ident} at offset {self.offset}{more}"


# (proto, src address, dst address, L4 offset, L4 end, fragment or None). For a fragment, proto is the
# protocol of the datagram it belongs to and the bytes from the L4 offset to the end are the fragment's
# (in IPv6, those after the Fragment header: the upper-layer header is in the first fragment only).
IpResult = tuple[int, bytes, bytes, int, int, FragmentInfo | None]


_POINTER_MIN = {7: (3, 4), 131: (3, 4), 137: (3, 4), 68: (4, 5)}  # RR, LSRR, SSRR, TS: least length, pointer


def options_problem(data: bytes, start: int, end: int) -> str | None:
    """What is wrong with the IPv4 options at data[start:end], as Linux's ip_options_compile finds it (a
    receiver drops the packet): an option cut short or whose length runs past the header, a record-route,
    source-route or timestamp option too short for its pointer or pointing before its data. None when they
    parse (their meaning is not judged)."""
    p = start
    while p < end:
        kind = data[p]
        if kind == 0:  # end of options
            return None
        if kind == 1:  # no operation
            p += 1
            continue
        if end - p < 2:
            return f"IPv4 option {kind} cut short at the end of the header"
        size = data[p + 1]
        if size < 2 or size > end - p:
            return f"IPv4 option {kind} of length {size} does not fit in the {end - p} bytes left of the header"
        least = _POINTER_MIN.get(kind)
        if least is not None and (size < least[0] or data[p + 2] < least[1]):
            return f"IPv4 option {kind} of length {size} has no room for its pointer, or it points before its data"
        p += size
    return None


def parse_ipv4(data: bytes, off: int, limit: int | None = None) -> IpResult | str:
    """Decode an IPv4 header at `off`; an error message (str) when it is malformed.

    The checksum is not looked at here (mavscope.transport.checksum judges it). The end of the layer-4
    data honours the total length, which strips Ethernet padding, clamped to the captured bytes (or to
    `limit`, where the packet's bytes end before the record's).
    """
    n = len(data) if limit is None else min(limit, len(data))
    if off + 20 > n:
        return f"IPv4 header cut short: {n - off} of 20 bytes"
    vihl, tos, total, ident, frag, _ttl, proto, src, dst = _IPV4.unpack_from(data, off)
    if vihl >> 4 != 4:
        return f"IPv4 header with version {vihl >> 4}"
    ihl = (vihl & 15) * 4
    if ihl < 20:
        return f"IPv4 header length {ihl} < 20"
    if off + ihl > n:
        return f"IPv4 options cut short: header length {ihl}, {n - off} bytes captured"
    if total == 0:  # TCP segmentation offload leaves it 0
        end = n
    elif total < ihl:
        return f"IPv4 total length {total} < header length {ihl}"
    else:
        end = min(off + total, n)
    fragment = None
    if frag & 0x3FFF:
        fragment = FragmentInfo(False, ident, (frag & 0x1FFF) * 8, bool(frag & 0x2000), ihl,
                                (total or n - off) - ihl, tos & 3)
    return proto, src, dst, off + ihl, end, fragment


def parse_ipv6(data: bytes, off: int, limit: int | None = None) -> IpResult | str:
    """Decode an IPv6 header at `off` and walk its extension headers to the upper-layer header, or to a
    Fragment header that makes the packet a fragment (an atomic one, offset 0 and no more, is walked past:
    RFC 8200 and Linux take it as a whole datagram)."""
    n = len(data) if limit is None else min(limit, len(data))
    if off + 40 > n:
        return f"IPv6 header cut short: {n - off} of 40 bytes"
    vcf, plen, nxt, _hops, src, dst = _IPV6.unpack_from(data, off)
    if vcf >> 28 != 6:
        return f"IPv6 header with version {vcf >> 28}"
    end = min(off + 40 + plen, n) if plen else n  # 0: jumbogram (hop-by-hop option) or offload
    walked = walk_ipv6(data, off + 40, end, nxt, jumbo=not plen)
    if isinstance(walked, str):
        return walked
    nxt, p, fragment = walked
    if fragment is not None:
        fragment = fragment._replace(length=off + 40 + plen - p, ecn=vcf >> 20 & 3)
    return nxt, src, dst, p, end, fragment


def walk_ipv6(data: bytes, p: int, end: int, nxt: int,
              jumbo: bool = False) -> tuple[int, int, FragmentInfo | None] | str:
    """Walk IPv6 extension headers from `p` (the first of type `nxt`) to the upper-layer header: (its
    type, its offset, None), or (the type after a Fragment header, the offset after it, the fragment).
    An atomic Fragment header (offset 0, no more) is walked past; in a `jumbo` packet (payload length 0) a
    Fragment header is an error (Linux drops it: a jumbogram cannot be fragmented)."""
    first = p
    for _ in range(MAX_EXT_HEADERS):
        if nxt in _EXT_SKIPPABLE:
            if p + 8 > end:
                return f"IPv6 extension header {nxt} cut short at byte {p}"
            nxt, hlen = data[p], (data[p + 1] + 1) * 8
            p += hlen
        elif nxt == EXT_FRAGMENT:
            if p + 8 > end:
                return f"IPv6 fragment header cut short at byte {p}"
            if jumbo:
                return f"IPv6 fragment header at byte {p} in a packet of payload length 0 (a jumbogram)"
            nxt2, offm, ident = _FRAG6.unpack_from(data, p)
            p += 8
            if offm & 0xFFF9:
                return nxt2, p, FragmentInfo(True, ident, offm & 0xFFF8, bool(offm & 1), p - 8 - first, end - p)
            nxt = nxt2
        else:
            break
    else:
        return f"more than {MAX_EXT_HEADERS} IPv6 extension headers"
    if p > end:
        return f"IPv6 extension headers run past the packet end at byte {end}"
    return nxt, p, None


class Endpoints:
    """Interns Endpoints by address and port, so the hot path rarely builds one (a capture has a handful)."""

    __slots__ = ("_v4", "_v6", "limit")

    def __init__(self, limit: int = 16384) -> None:
        self._v4: dict[int, Endpoint] = {}
        self._v6: dict[tuple[bytes, int], Endpoint] = {}
        self.limit = limit

    def v4(self, addr: int, port: int) -> Endpoint:
        """The Endpoint of IPv4 address `addr` (as a 32-bit integer) and `port`."""
        key = (addr << 16) | port
        ep = self._v4.get(key)
        if ep is None:
            if len(self._v4) >= self.limit:
                self._v4.clear()
            host = f"{addr >> 24}.{(addr >> 16) & 255}.{(addr >> 8) & 255}.{addr & 255}"
            ep = self._v4[key] = Endpoint(host, port, socket.AF_INET)
        return ep

    def v4_bytes(self, addr: bytes, port: int) -> Endpoint:
        """The Endpoint of a 4-byte IPv4 address and `port`."""
        return self.v4(int.from_bytes(addr, "big"), port)

    def v6(self, addr: bytes, port: int) -> Endpoint:
        """The Endpoint of a 16-byte IPv6 address and `port`."""
        key = (addr, port)
        ep = self._v6.get(key)
        if ep is None:
            if len(self._v6) >= self.limit:
                self._v6.clear()
            ep = self._v6[key] = Endpoint(socket.inet_ntop(socket.AF_INET6, addr), port, socket.AF_INET6)
        return ep
