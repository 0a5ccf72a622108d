"""Packets made up for datagrams that arrived without a link layer: an Ethernet/IPv4 or IPv6/UDP packet
with correct checksums around a payload, so that the offline pipeline, the pcap writer and Wireshark
serve them unchanged. Live UDP capture wraps every datagram it receives (with the real addresses);
`read -w` wraps the frames of a tlog or raw stream. One Internet checksum, one synthesis."""

from __future__ import annotations

import functools
import ipaddress
import struct

from mavscope.endpoint import Endpoint
from mavscope.errors import UsageError

_ETH_V4 = b"\x02\x00\x00\x00\x00\x02" + b"\x02\x00\x00\x00\x00\x01" + b"\x08\x00"
_ETH_V6 = b"\x02\x00\x00\x00\x00\x02" + b"\x02\x00\x00\x00\x00\x01" + b"\x86\xdd"
_IPV4 = struct.Struct("!BBHHHBBH4s4s")
_UDP = struct.Struct("!HHHH")


def internet_checksum(data: bytes) -> int:
    """The Internet checksum (RFC 1071) of `data`.

    The one's-complement sum of 16-bit words is the data read as one big number modulo 0xFFFF
    (2**16 = 1 mod 0xFFFF), with 0xFFFF rather than 0 for non-zero data: one C-level operation
    instead of a Python loop over the words (live capture synthesises a header per datagram).
    """
    if len(data) & 1:
        data += b"\0"
    value = int.from_bytes(data, "big")
    total = value % 0xFFFF
    if total == 0 and value:
        total = 0xFFFF
    return ~total & 0xFFFF


@functools.lru_cache(maxsize=4096)  # a live capture synthesises headers for the same few endpoints
def packed_address(host: str) -> bytes:
    """The packed address of a numeric host: 4 bytes for IPv4 and IPv4-mapped IPv6, else 16."""
    try:
        addr = ipaddress.ip_address(host.split("%")[0])  # an IPv6 scope (fe80::1%eth0) is not on the wire
    except ValueError:
        raise UsageError(f"not a numeric IP address: {host!r}") from None
    if isinstance(addr, ipaddress.IPv6Address) and addr.ipv4_mapped is not None:
        return addr.ipv4_mapped.packed
    return addr.packed


def udp_packet(src_host: str, src_port: int, dst_host: str, dst_port: int, payload: bytes) -> bytes:
    """Ethernet/IP/UDP carrying `payload`: IPv4 when both ends are IPv4 (or IPv4-mapped), else IPv6 (an
    IPv4 end then written IPv4-mapped). UsageError for a payload one IP packet cannot carry."""
    saddr, daddr = packed_address(src_host), packed_address(dst_host)
    ulen = 8 + len(payload)
    if len(saddr) == 4 and len(daddr) == 4:
        if 20 + ulen > 0xFFFF:
            raise UsageError(f"UDP payload of {len(payload)} bytes does not fit one IPv4 packet")
        csum = internet_checksum(saddr + daddr + struct.pack("!BBH", 0, 17, ulen)
                                 + _UDP.pack(src_port, dst_port, ulen, 0) + payload) or 0xFFFF
        header = bytearray(_IPV4.pack(0x45, 0, 20 + ulen, 0, 0x4000, 64, 17, 0, saddr, daddr))
        header[10:12] = struct.pack("!H", internet_checksum(bytes(header)))
        return _ETH_V4 + bytes(header) + _UDP.pack(src_port, dst_port, ulen, csum) + payload
    saddr, daddr = (a if len(a) == 16 else b"\0" * 10 + b"\xff\xff" + a for a in (saddr, daddr))
    if ulen > 0xFFFF:
        raise UsageError(f"UDP payload of {len(payload)} bytes does not fit one IPv6 packet")
    csum = internet_checksum(saddr + daddr + struct.pack("!IxxxB", ulen, 17)
                             + _UDP.pack(src_port, dst_port, ulen, 0) + payload) or 0xFFFF
    ip = struct.pack("!IHBB", 6 << 28, ulen, 17, 64) + saddr + daddr
    return _ETH_V6 + ip + _UDP.pack(src_port, dst_port, ulen, csum) + payload


def endpoint_packet(src: Endpoint, dst: Endpoint, payload: bytes) -> bytes:
    """`udp_packet` from `src` to `dst`."""
    return udp_packet(src.host, src.port, dst.host, dst.port, payload)
