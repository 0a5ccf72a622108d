"""Tunnels (mavscope.transport.tunnel): MAVLink inside IP-in-IP, IPv6-in-IP, GRE and VXLAN.

The packets are scapy's (IP, IPv6, GRE, VXLAN layers); the frames expected inside are pymavlink's parse of
the inner UDP payload, with the inner endpoints, and tshark (which decodes all four tunnels) with pymavlink's
Lua dissector finds the same frames in the same records. What does not fit is one note (RFC 2784/2890 for
GRE's optional fields, RFC 7348 for VXLAN's I flag, worked by hand below).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.inet import IP, UDP
from scapy.layers.inet6 import IPv6
from scapy.layers.l2 import GRE, Ether
from scapy.layers.vxlan import VXLAN
from scapy.packet import Packet, Raw
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.transport.decap import Decapsulator
from mavscope.transport.tunnel import MAX_DEPTH
from tests.support.builders import gcs_arm, gcs_heartbeat

MAC = {"src": "02:00:00:00:00:02", "dst": "02:00:00:00:00:01"}
OUTER = IP(src="10.0.0.2", dst="10.0.0.1")


FRAMES = gcs_heartbeat() + gcs_arm(1)  # a ground station's HEARTBEAT and ARM, as pymavlink packs them


def inner() -> Packet:
    return IP(src="172.17.0.2", dst="172.17.0.3") / UDP(sport=14550, dport=14555) / FRAMES


TUNNELS = {
    "ip-in-ip": Ether(**MAC) / OUTER / inner(),
    "gre": Ether(**MAC) / OUTER / GRE() / inner(),
    "gre with checksum, key and sequence": Ether(**MAC) / OUTER / GRE(chksum_present=1, key_present=1, key=7,
                                                                      seqnum_present=1, sequence_number=3) / inner(),
    "gre bridging ethernet": Ether(**MAC) / OUTER / GRE(proto=0x6558) / Ether(**MAC) / inner(),
    "vxlan": Ether(**MAC) / OUTER / UDP(sport=5555, dport=4789) / VXLAN(vni=42) / Ether(**MAC) / inner(),
    "ipv6 in ipv4": Ether(**MAC) / OUTER / IPv6(src="fd00::2", dst="fd00::3") / UDP(sport=14550, dport=14555)
    / FRAMES,
}


def feed(pkt: Packet | bytes) -> list:
    raw = bytes(pkt)
    return Decapsulator().feed(Record(1, 1.0, LINKTYPE_ETHERNET, raw, 0, len(raw)))


@pytest.mark.parametrize("name", TUNNELS)
def test_the_inner_datagram_is_read(name: str) -> None:
    out = feed(TUNNELS[name])
    assert len(out) == 1 and out[0].data == FRAMES and not out[0].notes
    want = ("[fd00::2]:14550", "[fd00::3]:14555") if "ipv6" in name else ("172.17.0.2:14550", "172.17.0.3:14555")
    assert (str(out[0].src), str(out[0].dst)) == want


def test_what_is_no_tunnel_or_does_not_fit() -> None:
    """VXLAN's I flag clear: no VXLAN, the datagram is read as any UDP (scanned for MAVLink). GRE version 1
    (PPTP) carries PPP: passed over. A GRE header whose flags announce a key that is not there, and tunnels
    nested past MAX_DEPTH, are one note."""
    plain = Ether(**MAC) / OUTER / UDP(sport=5555, dport=4789) / (bytes(8) + FRAMES)
    assert feed(plain)[0].data == bytes(8) + FRAMES
    assert feed(Ether(**MAC) / OUTER / Raw(b"\x30\x01\x88\x0b" + bytes(12))) == []  # proto 0 inside IP: ignored
    pptp = bytes(Ether(**MAC) / IP(src="10.0.0.2", dst="10.0.0.1", proto=47) / Raw(b"\x30\x01\x88\x0b" + bytes(8)))
    assert feed(pptp) == []
    cut = bytes(Ether(**MAC) / IP(src="10.0.0.2", dst="10.0.0.1", proto=47) / Raw(b"\x20\x00\x08\x00"))
    assert [n.code for n in feed(cut)[0].notes] == ["malformed-packet"]
    nested: Packet = inner()
    for _ in range(MAX_DEPTH + 1):
        nested = IP(src="10.0.0.2", dst="10.0.0.1") / nested
    out = feed(Ether(**MAC) / nested)
    assert not out[0].data and "inside 4 others" in out[0].notes[0].message
    nested = inner()
    for _ in range(MAX_DEPTH):
        nested = IP(src="10.0.0.2", dst="10.0.0.1") / nested
    assert feed(Ether(**MAC) / nested)[0].data == FRAMES


def expected_frames() -> list[tuple[int, int, int, int]]:
    """(record, sysid, compid, msgid) of what pymavlink parses from the inner payload, in each record."""
    parsed = [(f.get_srcSystem(), f.get_srcComponent(), f.get_msgId())
              for f in mavlink.MAVLink(None).parse_buffer(FRAMES)]
    return [(n, *p) for n in range(1, len(TUNNELS) + 1) for p in parsed]


def test_read_and_both_engines(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    pcap = tmp_path / "tunnels.pcap"
    wrpcap(str(pcap), list(TUNNELS.values()))
    assert [(f["frame"], f["sysid"], f["compid"], f["msgid"]) for f in cli.jsonl(pcap)] == expected_frames()
    for argv in (("read", pcap, "-T", "jsonl"), ("stats", pcap, "--json")):
        assert cli(*argv, environ={"MAVSCOPE_PURE": "0"}) == cli(*argv, environ={"MAVSCOPE_PURE": "1"})


def test_tshark_finds_the_same_frames(tmp_path: Path, tshark_exe: str, lua_dissector: Path) -> None:
    from tests.support import tshark

    pcap = tmp_path / "tunnels.pcap"
    wrpcap(str(pcap), list(TUNNELS.values()))
    run = tshark.run_lua_dissector(tshark_exe, lua_dissector, pcap, {14555})
    assert [(f.frame, f.sysid, f.compid, f.msgid) for f in run.frames()] == expected_frames()


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from([4, 41, 47, 17]), st.binary(max_size=80))
def test_any_tunnel_bytes_never_raise(proto: int, body: bytes) -> None:
    head = b"\x12\xb5\x12\xb5" + (8 + len(body)).to_bytes(2, "big") + b"\x00\x00" if proto == 17 else b""
    feed(Ether(**MAC) / IP(src="10.0.0.2", dst="10.0.0.1", proto=proto) / Raw(head + body))
