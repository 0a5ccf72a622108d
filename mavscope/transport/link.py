"""Link-layer headers: find the network-layer header (IPv4 or IPv6) inside a captured packet."""

from __future__ import annotations

import struct

from mavscope.capture.base import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IEEE802_11,
    LINKTYPE_IEEE802_11_RADIOTAP,
    LINKTYPE_IPV4,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
)
from mavscope.transport.air import Air
from mavscope.transport.wifi import Rebuilt, Subframes, Undecoded, strip_80211, strip_radiotap

ETHERTYPE_IPV4 = 0x0800
ETHERTYPE_IPV6 = 0x86DD
ETHERTYPE_VLAN = 0x8100  # 802.1Q
ETHERTYPE_QINQ = 0x88A8  # 802.1ad
ETHERTYPE_QINQ_OLD = 0x9100  # pre-standard QinQ
_VLAN_TYPES = frozenset((ETHERTYPE_VLAN, ETHERTYPE_QINQ, ETHERTYPE_QINQ_OLD))

# BSD loopback address families: AF_INET is 2 everywhere, AF_INET6 differs by OS
AF_INET = 2
AF_INET6 = frozenset((24, 28, 30))  # NetBSD/OpenBSD, FreeBSD, Darwin

_U16 = struct.Struct("!H").unpack_from
_U32LE = struct.Struct("<I").unpack_from
_U32BE = struct.Struct(">I").unpack_from

LinkResult = tuple[int, int] | str | Undecoded | Subframes | Rebuilt | None


def _family(af: int) -> int:
    """The ethertype for a BSD address family, 0 for one that is not IP."""
    if af == AF_INET:
        return ETHERTYPE_IPV4
    if af in AF_INET6:
        return ETHERTYPE_IPV6
    return 0


def _ip_version(data: bytes, off: int) -> int:
    """The ethertype for a bare IP header at `off`, from its version nibble (0 if neither 4 nor 6)."""
    if off >= len(data):
        return 0
    v = data[off] >> 4
    return ETHERTYPE_IPV4 if v == 4 else ETHERTYPE_IPV6 if v == 6 else 0


def ethernet_at(data: bytes, start: int) -> tuple[int, int] | str:
    """(ethertype, offset of what follows) of the Ethernet header at `start`, past its VLAN tags."""
    n = len(data)
    if start + 14 > n:
        return f"Ethernet header needs 14 bytes, packet has {n - start}"
    et = (data[start + 12] << 8) | data[start + 13]
    off = start + 14
    while et in _VLAN_TYPES:
        if off + 4 > n:
            return f"802.1Q tag cut short at byte {off}"
        et = (data[off + 2] << 8) | data[off + 3]
        off += 4
    if et < 0x0600:  # an 802.3 length field: LLC/SNAP, never IP for our purposes
        return (0, off)
    return (et, off)


def strip_link(linktype: int, data: bytes, air: Air | None = None, whole: bool = True) -> LinkResult:
    """Where the network header starts: (ethertype, offset) (`air`: the capture's 802.11 state, for the Wi-Fi
    link types; a decrypted frame comes back as its plaintext; `whole`: the record was not snapped, so that a
    radiotap frame's FCS is checked).

    Returns None for a link type this module does not decode, and an error message (str) when the link
    header is malformed or cut short. Non-IP packets come back with their ethertype (or 0) for the caller
    to ignore.
    """
    n = len(data)
    if linktype == LINKTYPE_ETHERNET:
        return ethernet_at(data, 0)
    if linktype == LINKTYPE_RAW:
        return (_ip_version(data, 0), 0)
    if linktype == LINKTYPE_IPV4:
        return (ETHERTYPE_IPV4, 0)
    if linktype == LINKTYPE_IPV6:
        return (ETHERTYPE_IPV6, 0)
    if linktype == LINKTYPE_NULL:
        if n < 4:
            return f"loopback header needs 4 bytes, packet has {n}"
        af = _U32LE(data)[0]
        if af > 0xFFFF:  # written on a big-endian host
            af = _U32BE(data)[0]
        return (_family(af), 4)
    if linktype == LINKTYPE_LOOP:
        if n < 4:
            return f"loopback header needs 4 bytes, packet has {n}"
        return (_family(_U32BE(data)[0]), 4)
    if linktype == LINKTYPE_LINUX_SLL:
        if n < 16:
            return f"Linux cooked header needs 16 bytes, packet has {n}"
        return (_U16(data, 14)[0], 16)
    if linktype == LINKTYPE_LINUX_SLL2:
        if n < 20:
            return f"Linux cooked v2 header needs 20 bytes, packet has {n}"
        return (_U16(data, 0)[0], 20)
    if linktype == LINKTYPE_IEEE802_11_RADIOTAP:
        return strip_radiotap(data, air, whole)
    if linktype == LINKTYPE_IEEE802_11:
        return strip_80211(data, air=air, whole=whole)
    return None
