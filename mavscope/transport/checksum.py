"""UDP and TCP checksums (RFC 768, RFC 793, RFC 8200 8.1): right, wrong, absent, or a sender's offload placeholder.

A receiving kernel verifies them and drops a datagram or segment whose checksum is wrong before any
application reads it (Linux: `udp_lib_checksum_complete`, `tcp_checksum_complete`). A capture taken on
the sending host shows what its kernel handed the NIC instead: with checksum offload (every Linux
loopback capture, SITL's included) the field holds the pseudo-header's sum, which the NIC (or nobody, on
loopback) completes; Windows' TCP/IP does the same for NDIS miniports ("Offloading Checksum Tasks").
That placeholder is recognised exactly and not judged.

The ones' complement sum of 16-bit big-endian words is the byte string read as one big-endian integer,
modulo 0xFFFF (2**16 is 1 modulo 0xFFFF), with 0 standing for 0xFFFF: one C call for a whole segment.
"""

from __future__ import annotations

from enum import Enum

PROTO_TCP = 6
PROTO_UDP = 17
_M = 0xFFFF


class Checksum(Enum):
    RIGHT = "right"
    ABSENT = "absent"  # UDP over IPv4 with the field 0: no checksum, which a receiver accepts
    OFFLOAD = "offload"  # what a sender's kernel leaves for its NIC to fill in: not judged
    WRONG = "wrong"  # a receiver that checks drops it (IPv6 UDP with the field 0 too)


def ones_sum(data: bytes, start: int, end: int) -> int:
    """The ones' complement sum of data[start:end] (zero-padded to an even length), modulo 0xFFFF."""
    value = int.from_bytes(data[start:end], "big")
    return (value << 8 if (end - start) & 1 else value) % _M


def pseudo_sum(src: bytes, dst: bytes, proto: int, length: int) -> int:
    """The ones' complement sum of the pseudo-header, modulo 0xFFFF (IPv4's and IPv6's hold the same words
    but for the addresses' length and the zeros)."""
    return (int.from_bytes(src, "big") + int.from_bytes(dst, "big") + proto + length) % _M


def judge(v6: bool, src: bytes, dst: bytes, proto: int, data: bytes, l4: int, end: int) -> tuple[Checksum, int, int]:
    """The checksum of the UDP or TCP segment data[l4:end] (all of it captured): its verdict, the field's
    value and the value that would be right (the field's own when it is right)."""
    at = l4 + (6 if proto == PROTO_UDP else 16)
    field = data[at] << 8 | data[at + 1]
    udp0 = field == 0 and proto == PROTO_UDP
    if udp0 and not v6:
        return Checksum.ABSENT, 0, 0
    pseudo = pseudo_sum(src, dst, proto, end - l4)
    total = (pseudo + ones_sum(data, l4, end)) % _M
    if udp0:  # IPv6 requires one (Linux drops it unless told otherwise: udp6_csum_init)
        pass
    elif total == 0:  # the sum of every word is 0xFFFF: right
        return Checksum.RIGHT, field, field
    elif field == (pseudo or _M):
        return Checksum.OFFLOAD, field, field
    rest = (total - field) % _M  # the sum without the field
    right = _M - rest if rest else (_M if proto == PROTO_UDP else 0)
    return Checksum.WRONG, field, right


def ipv4_header(data: bytes, off: int, ihl: int) -> tuple[Checksum, int, int]:
    """The checksum of the IPv4 header of `ihl` bytes at `off`: its verdict, the field and the right value.
    Linux computes it in software always; a field of 0 is what a sender that leaves it to its NIC shows
    (macOS on its loopback, judep90's capture; Windows with IP checksum offload): not judged."""
    field = data[off + 10] << 8 | data[off + 11]
    if field == 0:
        return Checksum.OFFLOAD, 0, 0
    total = ones_sum(data, off, off + ihl)
    if total == 0:
        return Checksum.RIGHT, field, field
    rest = (total - field) % _M
    return Checksum.WRONG, field, _M - rest if rest else 0
