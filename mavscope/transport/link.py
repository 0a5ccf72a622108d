"""Link-layer headers: find the network-layer header (IPv4 or IPv6) inside a captured packet."""

from __future__ import annotations

import struct
from collections.abc import Callable

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


_FAMILIES = {AF_INET: ETHERTYPE_IPV4, **dict.fromkeys(AF_INET6, ETHERTYPE_IPV6)}  # BSD address family -> ethertype
_IP_VERSIONS = {4: ETHERTYPE_IPV4, 6: ETHERTYPE_IPV6}  # a bare IP header's version nibble -> ethertype


def _ip_version(data: bytes, off: int) -> int:
    """The ethertype for a bare IP header at `off`, from its version nibble (0 if neither 4 nor 6)."""
    if off >= len(data):
        return 0
    return _IP_VERSIONS.get(data[off] >> 4, 0)


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


# The link-layer decoders, one a link type: (data, air, whole) -> LinkResult (`air`: the capture's 802.11 state,
# for the Wi-Fi link types, a decrypted frame coming back as its plaintext; `whole`: the record was not snapped,
# so that a radiotap frame's FCS is checked). Each returns (ethertype or 0 for a packet that is not IP, offset
# of the network header), or an error message (str) when the link header is malformed or cut short.
LinkDecoder = Callable[[bytes, Air | None, bool], LinkResult]


def ethernet(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """Ethernet II (and 802.3), past 802.1Q / 802.1ad tags."""
    return ethernet_at(data, 0)


def raw_ip(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """LINKTYPE_RAW: a bare IPv4 or IPv6 header, told by its version nibble."""
    return (_ip_version(data, 0), 0)


def ipv4(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """LINKTYPE_IPV4: a bare IPv4 header."""
    return (ETHERTYPE_IPV4, 0)


def ipv6(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """LINKTYPE_IPV6: a bare IPv6 header."""
    return (ETHERTYPE_IPV6, 0)


def bsd_null(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """BSD loopback: a 4-byte address family in the capturing host's byte order."""
    if len(data) < 4:
        return f"loopback header needs 4 bytes, packet has {len(data)}"
    af = _U32LE(data)[0]
    if af > 0xFFFF:  # written on a big-endian host
        af = _U32BE(data)[0]
    return (_FAMILIES.get(af, 0), 4)


def openbsd_loop(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """OpenBSD loopback: a 4-byte address family in network byte order."""
    if len(data) < 4:
        return f"loopback header needs 4 bytes, packet has {len(data)}"
    return (_FAMILIES.get(_U32BE(data)[0], 0), 4)


def linux_sll(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """Linux cooked capture (any interface): 16 bytes, the protocol last."""
    if len(data) < 16:
        return f"Linux cooked header needs 16 bytes, packet has {len(data)}"
    return (_U16(data, 14)[0], 16)


def linux_sll2(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """Linux cooked capture v2: 20 bytes, the protocol first."""
    if len(data) < 20:
        return f"Linux cooked v2 header needs 20 bytes, packet has {len(data)}"
    return (_U16(data, 0)[0], 20)


def radiotap(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """802.11 behind a radiotap header (monitor mode)."""
    return strip_radiotap(data, air, whole)


def ieee802_11(data: bytes, air: Air | None, whole: bool) -> LinkResult:
    """Bare 802.11 frames."""
    return strip_80211(data, air=air, whole=whole)
