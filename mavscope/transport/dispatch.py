"""Transport dispatch as data: the decoder each link type, ethertype, IP protocol and UDP port leads to.

A layer looks the next one up by a number in its header, as Wireshark's dissector tables do ("ethertype",
"ip.proto", "udp.port": a dissector registers itself with `dissector_add_uint("udp.port", 4789, handle)`) and
scapy's `bind_layers(UDP, VXLAN, dport=4789)`; the Decapsulator (mavscope.transport.decap) holds no chain of
tests over these numbers, only lookups in:

- `LINK_TYPES`: a pcap link type -> a link decoder (mavscope.transport.link: `(data, air, whole)` -> (ethertype,
  offset of the network header) or what is wrong). An unknown link type is noted once per capture.
- `BYTE_LINK_TYPES`: the link types whose records are MAVLink bytes as they are (a tlog's entries, a raw
  serial stream) -> how they are handed on (`ByteLink`: the transport, and the stream key of a byte stream).
- `ETHERTYPES`: an ethertype (or a BSD address family's, a bare IP header's) -> the IP version that decodes it
  (802.1Q / 802.1ad tags are walked past inside Ethernet headers: mavscope.transport.link VLAN_TYPES).
- `IP_PROTOCOLS`: an IP protocol number -> its decoder `(layers, packet)` -> (Payloads, notes): UDP and TCP
  (mavscope.transport.upper), and tunnels (`Tunnel`: IP-in-IP 4, IPv6-in-IP 41, GRE 47), whose inner packet
  goes back to ETHERTYPES.
- `UDP_PORTS`: a UDP destination port -> a `Tunnel` its datagrams are tried as (VXLAN: 4789, and 8472, the
  Linux kernel's default), or `PortRole.MAVLINK` for MAVLink's conventional ports (a datagram to or from one
  is scanned as MAVLink even before a valid frame proves its sender: mavscope.pipeline.dissect).

`TABLES` holds them; a Decapsulator reads its tables when it is made (`Decapsulator(tables=...)`, TABLES by
default), so bind before opening a capture. Binding an entry, the way a user would:

    from mavscope.transport import dispatch
    from mavscope.transport.link import ETHERTYPE_IPV4, ethernet_at
    from mavscope.transport.tunnel import vxlan

    dispatch.bind_udp_port(4790, dispatch.Tunnel("VXLAN", vxlan))  # an overlay on another port
    dispatch.bind_udp_port(14445, dispatch.PortRole.MAVLINK)  # a ground station's own port

    def etherip(data, start, end):  # RFC 3378: 2 bytes of version, then an Ethernet frame
        return ethernet_at(data[:end], start + 2)

    dispatch.bind_ip_protocol(97, dispatch.Tunnel("EtherIP", etherip))
    dispatch.bind_link_type(147, lambda data, air, whole: (ETHERTYPE_IPV4, 4))  # a private DLT: 4 bytes, IPv4

or on a copy, for one capture: `tables = dispatch.TABLES.copy(); tables.bind_udp_port(...);
Decapsulator(tables=tables)`. The native core (src/mavscope_native/netlayers.c) decodes the built-in entries
itself: where `TABLES.builtin()` is False, the bindings are read by the pure-Python path (MAVSCOPE_PURE=1).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass

from mavscope.capture.base import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IEEE802_11,
    LINKTYPE_IEEE802_11_RADIOTAP,
    LINKTYPE_IPV4,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_MAVLINK_RAW,
    LINKTYPE_MAVLINK_TLOG,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
)
from mavscope.transport import link
from mavscope.transport.base import TRANSPORT_RAW, TRANSPORT_TLOG
from mavscope.transport.ip import PROTO_TCP, PROTO_UDP, IpResult, parse_ipv4, parse_ipv6
from mavscope.transport.link import ETHERTYPE_IPV4, ETHERTYPE_IPV6, LinkDecoder
from mavscope.transport.packet import Carrier, Decoded, Layers, Packet, PortRole, Tunnel, Upper
from mavscope.transport.tunnel import (
    PROTO_GRE,
    PROTO_IPIP,
    PROTO_IPV6_IN_IP,
    VXLAN_PORT,
    VXLAN_PORT_LINUX,
    gre,
    ipip,
    ipv6_in_ip,
    vxlan,
)
from mavscope.transport.upper import tcp, udp

__all__ = ["TABLES", "ByteLink", "Carrier", "Decoded", "IpVersion", "Layers", "Packet", "PortRole", "Tables",
           "Tunnel", "Upper", "bind_ethertype", "bind_ip_protocol", "bind_link_type", "bind_udp_port"]

RAW_STREAM = (TRANSPORT_RAW,)  # the stream key of a raw byte-stream capture


@dataclass(frozen=True, slots=True)
class ByteLink:
    """A link type whose records are MAVLink bytes: the transport they are handed on as, and the stream key
    (None: each record is a datagram of its own, a tlog entry; else the bytes run on from record to record)."""

    transport: str
    stream: Hashable | None


@dataclass(frozen=True, slots=True)
class IpVersion:
    """The IP version an ethertype leads to: `v4` (IPv4's header checksum, options and total length are
    judged; IPv6's payload length and extension headers), and its header's parser (mavscope.transport.ip)."""

    v4: bool
    parse: Callable[[bytes, int, int | None], IpResult | str]


IPV4 = IpVersion(True, parse_ipv4)
IPV6 = IpVersion(False, parse_ipv6)
VXLAN = Tunnel("VXLAN", vxlan)  # RFC 7348

LINK_TYPES: dict[int, LinkDecoder] = {
    LINKTYPE_ETHERNET: link.ethernet,
    LINKTYPE_RAW: link.raw_ip,
    LINKTYPE_IPV4: link.ipv4,
    LINKTYPE_IPV6: link.ipv6,
    LINKTYPE_NULL: link.bsd_null,
    LINKTYPE_LOOP: link.openbsd_loop,
    LINKTYPE_LINUX_SLL: link.linux_sll,
    LINKTYPE_LINUX_SLL2: link.linux_sll2,
    LINKTYPE_IEEE802_11_RADIOTAP: link.radiotap,
    LINKTYPE_IEEE802_11: link.ieee802_11,
}
BYTE_LINK_TYPES: dict[int, ByteLink] = {
    LINKTYPE_MAVLINK_TLOG: ByteLink(TRANSPORT_TLOG, None),
    LINKTYPE_MAVLINK_RAW: ByteLink(TRANSPORT_RAW, RAW_STREAM),
}
ETHERTYPES: dict[int, IpVersion] = {ETHERTYPE_IPV4: IPV4, ETHERTYPE_IPV6: IPV6}
IP_PROTOCOLS: dict[int, Upper] = {
    PROTO_UDP: udp,
    PROTO_TCP: tcp,
    PROTO_IPIP: Tunnel("IP-in-IP", ipip),  # RFC 2003
    PROTO_IPV6_IN_IP: Tunnel("IP-in-IP", ipv6_in_ip),  # RFC 4213
    PROTO_GRE: Tunnel("GRE", gre),  # RFC 2784, 2890
}
# MAVLink's ports by convention (DOMAIN.md: UDP 14550 a GCS's, 14540/14580 PX4 SITL's offboard/onboard, 18570;
# 5760-5763 ArduPilot SITL's), with 14555, 14557 and 14560 (more SITL instances and links)
MAVLINK_CONVENTIONAL = (14550, 14540, 14555, 14557, 14560, 14580, 18570, 5760, 5761, 5762, 5763)
UDP_PORTS: dict[int, Tunnel | PortRole] = {
    VXLAN_PORT: VXLAN,
    VXLAN_PORT_LINUX: VXLAN,
    **dict.fromkeys(MAVLINK_CONVENTIONAL, PortRole.MAVLINK),
}


def _check(key: int, bits: int, what: str) -> None:
    if not 0 <= key < 1 << bits:
        raise ValueError(f"{what} {key} is not a {bits}-bit number")


@dataclass(frozen=True, slots=True)
class Tables:
    """The dispatch tables one Decapsulator reads (see the module's text)."""

    link_types: dict[int, LinkDecoder]
    byte_link_types: dict[int, ByteLink]
    ethertypes: dict[int, IpVersion]
    ip_protocols: dict[int, Upper]
    udp_ports: dict[int, Tunnel | PortRole]

    def copy(self) -> Tables:
        """Tables of their own with the same entries (binding in them leaves these as they are)."""
        return Tables(dict(self.link_types), dict(self.byte_link_types), dict(self.ethertypes),
                      dict(self.ip_protocols), dict(self.udp_ports))

    def bind_link_type(self, linktype: int, decoder: LinkDecoder | ByteLink) -> None:
        """Decode records of pcap link type `linktype` with `decoder` (a ByteLink: they are MAVLink bytes)."""
        _check(linktype, 32, "link type")
        self.link_types.pop(linktype, None)
        self.byte_link_types.pop(linktype, None)
        if isinstance(decoder, ByteLink):
            self.byte_link_types[linktype] = decoder
        else:
            self.link_types[linktype] = decoder

    def bind_ethertype(self, ethertype: int, version: IpVersion) -> None:
        """Decode packets of `ethertype` as IP of `version` (IPV4 or IPV6)."""
        _check(ethertype, 16, "ethertype")
        self.ethertypes[ethertype] = version

    def bind_ip_protocol(self, proto: int, decoder: Upper) -> None:
        """Decode the payload of IP packets of protocol `proto` with `decoder` (a Tunnel, say)."""
        _check(proto, 8, "IP protocol")
        self.ip_protocols[proto] = decoder

    def bind_udp_port(self, port: int, binding: Tunnel | PortRole) -> None:
        """Try datagrams to UDP port `port` as `binding`'s tunnel, or take the port for MAVLink's."""
        _check(port, 16, "UDP port")
        self.udp_ports[port] = binding

    def mavlink_ports(self) -> frozenset[int]:
        """The UDP ports bound to MAVLink."""
        return frozenset(p for p, b in self.udp_ports.items() if b is PortRole.MAVLINK)

    def tunnel_ports(self) -> frozenset[int]:
        """The UDP ports a tunnel is bound to."""
        return frozenset(p for p, b in self.udp_ports.items() if isinstance(b, Tunnel))

    def fast_path(self) -> bool:
        """Whether Ethernet, IPv4 and UDP lead to the built-in decoders (the Decapsulator's fast path assumes so)."""
        return (self.link_types.get(LINKTYPE_ETHERNET) is link.ethernet and self.ethertypes.get(ETHERTYPE_IPV4) is IPV4
                and self.ip_protocols.get(PROTO_UDP) is udp)

    def builtin(self) -> bool:
        """Whether these tables hold the built-in entries and no others (the native core's own)."""
        return self == _BUILTIN


TABLES = Tables(LINK_TYPES, BYTE_LINK_TYPES, ETHERTYPES, IP_PROTOCOLS, UDP_PORTS)
_BUILTIN = TABLES.copy()
bind_link_type = TABLES.bind_link_type
bind_ethertype = TABLES.bind_ethertype
bind_ip_protocol = TABLES.bind_ip_protocol
bind_udp_port = TABLES.bind_udp_port
