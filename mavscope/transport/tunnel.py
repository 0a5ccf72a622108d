"""Tunnels: the packet inside IP-in-IP (4), IPv6-in-IP (41), GRE (47) and VXLAN (UDP 4789, and 8472,
the Linux kernel's own default).

A capture taken on a host whose SITL, companion computer or ground station sits behind an overlay
network (Docker Swarm and Kubernetes overlays are VXLAN), a GRE or IP-in-IP tunnel has the MAVLink
datagrams inside the tunnel's packets; the endpoints that matter are the inner ones, which the vehicle
and the ground station use. Layouts: RFC 2003 (IP-in-IP), RFC 4213 (IPv6 in IPv4), RFC 2784 and 2890
(GRE: checksum, key and sequence fields by their flags), RFC 7348 (VXLAN: 8 bytes, the I flag, then
an Ethernet frame).
"""

from __future__ import annotations

from mavscope.transport.link import ETHERTYPE_IPV4, ETHERTYPE_IPV6, ethernet_at

PROTO_IPIP = 4
PROTO_IPV6_IN_IP = 41
PROTO_GRE = 47
VXLAN_PORT = 4789  # IANA's
VXLAN_PORT_LINUX = 8472  # the Linux kernel's default
ETHERTYPE_TEB = 0x6558  # GRE's transparent Ethernet bridging: an Ethernet frame inside
MAX_DEPTH = 4  # tunnels inside tunnels decoded at most

# (ethertype or 0: not IP, offset of the inner header), a problem, or None: not this tunnel after all (a UDP
# datagram to a tunnel's port that is not the tunnel's is read as any other datagram)
Inner = tuple[int, int] | str | None


def ipip(data: bytes, start: int, end: int) -> Inner:
    """The IPv4 packet inside an IP-in-IP packet (RFC 2003) whose payload starts at `start`."""
    return (ETHERTYPE_IPV4, start)


def ipv6_in_ip(data: bytes, start: int, end: int) -> Inner:
    """The IPv6 packet inside an IPv6-in-IP packet (RFC 4213) whose payload starts at `start`."""
    return (ETHERTYPE_IPV6, start)


def gre(data: bytes, l4: int, end: int) -> Inner:
    """The packet inside the GRE header at `l4`."""
    if l4 + 4 > end:
        return f"GRE header cut short at byte {l4}"
    flags = (data[l4] << 8) | data[l4 + 1]
    if flags & 7:
        return (0, l4)  # version 1 (PPTP's enhanced GRE) carries PPP, not IP
    et = (data[l4 + 2] << 8) | data[l4 + 3]
    off = l4 + 4 + 4 * ((flags >> 15 & 1) + (flags >> 13 & 1) + (flags >> 12 & 1))  # checksum, key, sequence
    if off > end:
        return f"GRE header of {off - l4} bytes cut short at byte {end}"
    if et == ETHERTYPE_TEB:
        return ethernet_at(data[:end], off)
    return (et, off)


def vxlan(data: bytes, payload: int, end: int) -> Inner:
    """The packet inside the VXLAN header at `payload` (a UDP payload to a VXLAN port); None when its I flag
    is clear (not VXLAN: the datagram is read as any other)."""
    if payload + 8 > end or not data[payload] & 0x08:
        return None
    return ethernet_at(data[:end], payload + 8)
