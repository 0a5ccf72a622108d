"""The transport dispatch is its tables (mavscope.transport.dispatch): binding an entry in a copy of them makes a
packet that uses it decode, unbinding one stops it, and the Decapsulator holds no chain of tests over link types,
ethertypes, IP protocols or ports.

The packets are scapy's; the payloads expected are worked by hand from the layouts (the byte offsets summed from
the header sizes: Ethernet 14, IPv4 20, UDP 8, VXLAN 8 (RFC 7348), EtherIP 2 (RFC 3378)), the endpoints are the
addresses and ports the packets were built with, the MAVLink bytes pymavlink's.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import Ether
from scapy.layers.vxlan import VXLAN
from scapy.packet import Packet, Raw

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.pipeline.dissect import Dissector
from mavscope.transport import dispatch
from mavscope.transport.base import TRANSPORT_UDP, Payload
from mavscope.transport.decap import Decapsulator
from mavscope.transport.dispatch import IPV4, TABLES, PortRole, Tables, Tunnel
from mavscope.transport.ip import PROTO_UDP
from mavscope.transport.link import ETHERTYPE_IPV4, ethernet_at
from mavscope.transport.tunnel import Inner, vxlan
from tests.conftest import ROOT
from tests.support.pmav import heartbeat, mav2

OUTER = IP(src="10.0.0.2", dst="10.0.0.1")
FRAMES = heartbeat(mav2(1, 1))
INNER_SRC, INNER_DST = Endpoint("172.17.0.2", 14550), Endpoint("172.17.0.3", 14555)


def eth(ethertype: int | None = None) -> Packet:
    mac = Ether(src="02:00:00:00:00:02", dst="02:00:00:00:00:01")
    if ethertype is not None:
        mac.type = ethertype
    return mac


def inner() -> Packet:
    return IP(src="172.17.0.2", dst="172.17.0.3") / UDP(sport=14550, dport=14555) / FRAMES


def decode(pkt: Packet | bytes, tables: Tables = TABLES, linktype: int = LINKTYPE_ETHERNET) -> list[Payload]:
    raw = bytes(pkt)
    return Decapsulator(tables=tables).feed(Record(1, 1.0, linktype, raw, 0, len(raw)))


def inner_payload(offset: int) -> list[Payload]:
    """The inner datagram's payload, at file `offset` (the record at file offset 0)."""
    return [Payload(TRANSPORT_UDP, INNER_SRC, INNER_DST, FRAMES, None, 1, offset)]


def test_a_tunnel_bound_to_a_new_udp_port() -> None:
    """VXLAN to port 4790 (not one of its own): a plain datagram by the built-in tables, VXLAN's inner datagram
    once the port is bound in a copy (the fast path for Ethernet/IPv4/UDP included: it asks the tables)."""
    pkt = eth() / OUTER / UDP(sport=5555, dport=4790) / VXLAN(vni=42) / eth() / inner()
    tables = TABLES.copy()
    tables.bind_udp_port(4790, Tunnel("VXLAN", vxlan))
    assert decode(pkt, tables) == inner_payload(14 + 20 + 8 + 8 + 14 + 20 + 8)
    outer = decode(pkt)  # the built-in tables are as they were
    assert [(str(p.dst), p.offset) for p in outer] == [("10.0.0.1:4790", 14 + 20 + 8)]
    assert 4790 not in TABLES.udp_ports and TABLES.builtin() and not tables.builtin()


def etherip(data: bytes, start: int, end: int) -> Inner:
    """RFC 3378: 4 bits of version (3), 12 reserved, then an Ethernet frame."""
    return ethernet_at(data[:end], start + 2)


def test_a_tunnel_bound_to_a_new_ip_protocol() -> None:
    pkt = eth() / IP(src="10.0.0.2", dst="10.0.0.1", proto=97) / Raw(b"\x30\x00") / eth() / inner()
    assert decode(pkt) == []  # protocol 97 is not decoded: passed over, as any protocol but UDP, TCP and tunnels
    tables = TABLES.copy()
    tables.bind_ip_protocol(97, Tunnel("EtherIP", etherip))
    assert decode(pkt, tables) == inner_payload(14 + 20 + 2 + 14 + 20 + 8)
    # the inner Ethernet header cut short (10 of 14 bytes): one note, named by the tunnel
    cut = eth() / IP(src="10.0.0.2", dst="10.0.0.1", proto=97) / Raw(b"\x30\x00" + bytes(10))
    (got,) = decode(cut, tables)
    assert [(n.code, n.message) for n in got.notes] == [
        ("malformed-packet", "EtherIP: Ethernet header needs 14 bytes, packet has 10")]


def test_a_new_link_type_and_a_new_ethertype() -> None:
    """A private link type (147, DLT_USER0) with a 4-byte header before IPv4, and an ethertype (0x88B5, IEEE's
    local experimental one) bound to IPv4."""
    datagram = bytes(IP(src="172.17.0.2", dst="172.17.0.3") / UDP(sport=14550, dport=14555) / FRAMES)
    tables = TABLES.copy()
    tables.bind_link_type(147, lambda data, air, whole: (ETHERTYPE_IPV4, 4))
    (unknown,) = decode(b"\0\0\0\0" + datagram, linktype=147)
    assert [n.code for n in unknown.notes] == ["unknown-linktype"] and not unknown.data
    assert decode(b"\0\0\0\0" + datagram, tables, 147) == inner_payload(4 + 20 + 8)
    pkt = eth(0x88B5) / Raw(datagram)
    assert decode(pkt) == []  # not IP
    tables.bind_ethertype(0x88B5, IPV4)
    assert decode(pkt, tables) == inner_payload(14 + 20 + 8)


def test_unbinding_stops_the_decoding_fast_path_included() -> None:
    """A clean Ethernet/IPv4/UDP datagram (the fast path's kind) is not read once UDP or Ethernet is bound away."""
    pkt = eth() / inner()
    assert decode(pkt) == inner_payload(14 + 20 + 8)
    no_udp = TABLES.copy()
    del no_udp.ip_protocols[PROTO_UDP]
    assert decode(pkt, no_udp) == []
    not_ip = TABLES.copy()
    not_ip.bind_link_type(LINKTYPE_ETHERNET, lambda data, air, whole: (0, 14))
    assert decode(pkt, not_ip) == []
    assert TABLES.fast_path() and not no_udp.fast_path() and not not_ip.fast_path()


def test_a_port_bound_to_mavlink(dialect: Dialect, monkeypatch: pytest.MonkeyPatch) -> None:
    """A datagram whose one frame has a wrong CRC, between two ports MAVLink does not use by convention and from
    a source not yet proven: not scanned as MAVLink, until its port is bound to MAVLink (in the default tables,
    as a user would before opening the capture)."""
    bad = bytearray(FRAMES)
    bad[-1] ^= 0xFF  # the CRC's high byte (MAVLink 2: the checksum ends an unsigned frame)
    raw = bytes(eth() / IP(src="172.17.0.2", dst="172.17.0.3") / UDP(sport=14446, dport=14445) / bytes(bad))
    rec = Record(1, 1.0, LINKTYPE_ETHERNET, raw, 0, len(raw))

    def frames() -> list[tuple[int, CrcStatus]]:
        return [(i.msgid, i.crc_status) for i in Dissector(dialect).run([rec]) if isinstance(i, Frame)]

    assert frames() == []
    monkeypatch.setitem(dispatch.UDP_PORTS, 14445, PortRole.MAVLINK)
    assert frames() == [(0, CrcStatus.BAD)]  # HEARTBEAT


def test_bindings_are_checked() -> None:
    tables = TABLES.copy()
    with pytest.raises(ValueError):
        tables.bind_udp_port(65536, PortRole.MAVLINK)
    with pytest.raises(ValueError):
        tables.bind_ip_protocol(256, Tunnel("EtherIP", etherip))
    with pytest.raises(ValueError):
        tables.bind_ethertype(-1, IPV4)
    assert tables == TABLES


# the names a chain of tests over the dispatch would compare against
_DISPATCH_NAME = ("LINKTYPE_", "ETHERTYPE_", "PROTO_", "VXLAN_", "TUNNEL_", "AF_INET")


def _compared_names(tree: ast.AST) -> set[str]:
    """The dispatch constants in the comparisons (==, !=, in, not in) under `tree`."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            for side in (node.left, *node.comparators):
                name = side.id if isinstance(side, ast.Name) else side.attr if isinstance(side, ast.Attribute) else ""
                if name.startswith(_DISPATCH_NAME) or name.endswith("_PORTS"):
                    found.add(name)
    return found


def dispatch_comparisons(path: Path) -> dict[str, set[str]]:
    """The dispatch constants compared against in each function of the module at `path`."""
    tree = ast.parse(path.read_text())
    return {f.name: names for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
            if (names := _compared_names(f))}


def test_no_if_chain_over_the_dispatch() -> None:
    """decap.py looks its layers up in the tables; only its fast path (`feed`: Ethernet/IPv4/UDP, on while the
    tables bind those to the built-in decoders) names a link type. The other modules of the dispatch compare
    against none (link.py's BSD address families and IP versions are tables too)."""
    transport = ROOT / "mavscope" / "transport"
    assert dispatch_comparisons(transport / "decap.py") == {"feed": {"LINKTYPE_ETHERNET"}}
    for name in ("link.py", "upper.py", "packet.py", "dispatch.py"):
        assert dispatch_comparisons(transport / name) == {}, name


def test_the_meta_check_finds_a_chain() -> None:
    """The check above is not vacuous: an if-chain over link types and ports, as decap.py had (its `_slow`,
    `_network` and `_layer4` before the tables), is found."""
    code = ("def f(linktype, dport):\n    if linktype == LINKTYPE_MAVLINK_TLOG:\n        return 1\n"
            "    elif linktype == c.LINKTYPE_RAW or dport in VXLAN_PORTS:\n        return 2\n")
    assert _compared_names(ast.parse(code)) == {"LINKTYPE_MAVLINK_TLOG", "LINKTYPE_RAW", "VXLAN_PORTS"}


def test_a_binding_of_ones_own_puts_the_python_pipeline_in_charge(monkeypatch: pytest.MonkeyPatch) -> None:
    """The native core decodes the built-in entries alone (netlayers.c): with a binding added the engine
    is the Python pipeline's, which reads the tables (native.core.available)."""
    from mavscope.native import core
    from mavscope.transport import dispatch

    built = core.available({})
    assert not built or dispatch.TABLES.builtin()
    monkeypatch.setattr(dispatch, "TABLES", dispatch.TABLES.copy())
    monkeypatch.setattr(core, "TABLES", dispatch.TABLES)
    dispatch.TABLES.bind_udp_port(4790, dispatch.TABLES.udp_ports[4789])
    assert not dispatch.TABLES.builtin() and not core.available({})
