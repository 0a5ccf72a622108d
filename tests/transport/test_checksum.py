"""UDP and TCP checksums: what a receiving kernel drops, told from what a sender's checksum offload leaves.

Expected answers come from elsewhere than mavscope: scapy computes every right checksum (its UDP/TCP
layers, `in4_chksum`/`in6_chksum`, `checksum` for pseudo-headers), tshark judges them (`-o
udp.check_checksum:TRUE`, its `*.checksum.status` and `*.checksum_calculated` fields), and pymavlink
parses the bytes a receiver keeps.
"""

from __future__ import annotations

import json
import struct
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.inet6 import IPv6
from scapy.layers.l2 import Ether
from scapy.utils import checksum, rdpcap, wrpcap

from mavscope.capture.detect import open_capture
from mavscope.transport.checksum import PROTO_TCP, PROTO_UDP, Checksum, judge
from mavscope.transport.decap import Decapsulator
from tests.support.builders import gcs_arm, gcs_heartbeat

MACS = {"src": "02:00:00:00:00:02", "dst": "02:00:00:00:00:01"}
V4 = {"src": "10.0.0.2", "dst": "10.0.0.1"}
V6 = {"src": "fd00::2", "dst": "fd00::1"}
ENGINES = ({"MAVSCOPE_PURE": "0"}, {"MAVSCOPE_PURE": "1"})


def pseudo_sum(src: bytes, dst: bytes, proto: int, length: int) -> int:
    """The folded sum of a pseudo-header (what Linux leaves in the field for the NIC): scapy's `checksum`
    is its complement."""
    v6 = len(src) == 16
    pseudo = src + dst + (struct.pack("!IxxxB", length, proto) if v6 else struct.pack("!xBH", proto, length))
    return 0xFFFF - checksum(pseudo) or 0xFFFF


def layers(raw: bytes) -> tuple[bool, bytes, bytes, int, int]:
    """(IPv6, source, destination, protocol, layer-4 offset) of an unfragmented IP packet without options."""
    if raw[0] >> 4 == 6:
        return True, raw[8:24], raw[24:40], raw[6], 40
    return False, raw[12:16], raw[16:20], raw[9], 20


def field_at(proto: int, l4: int) -> int:
    return l4 + (6 if proto == PROTO_UDP else 16)


# --- the judgement --------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.booleans(), st.booleans(), st.binary(max_size=80), st.integers(0, 0xFFFF), st.integers(0, 2))
def test_judge_against_scapys_checksums(v6: bool, tcp: bool, payload: bytes, other: int, kind: int) -> None:
    """scapy's right checksum is right; any other value is wrong with scapy's value named as the right one,
    except 0 over IPv4 UDP (none) and the pseudo-header's sum, with or without the length (a sender's offload
    placeholder). `other` is drawn among those too."""
    l4 = TCP(sport=40000, dport=5760) if tcp else UDP(sport=14550, dport=14555)
    raw = bytes((IPv6(**V6) if v6 else IP(**V4)) / l4 / payload)
    six, src, dst, proto, off = layers(raw)
    at = field_at(proto, off)
    right = int.from_bytes(raw[at:at + 2], "big")
    assert judge(six, src, dst, proto, raw, off, len(raw)) == (Checksum.RIGHT, right, right)
    if kind:  # a placeholder: the pseudo-header's sum with the length (1) or without (2)
        other = pseudo_sum(src, dst, proto, len(raw) - off if kind == 1 else 0)
    if other == right:
        return
    bad = raw[:at] + struct.pack("!H", other) + raw[at + 2:]
    got = judge(six, src, dst, proto, bad, off, len(bad))
    if other == 0 and proto == PROTO_UDP and not v6:
        assert got == (Checksum.ABSENT, 0, 0)
    elif other in (pseudo_sum(src, dst, proto, len(raw) - off), pseudo_sum(src, dst, proto, 0)) and not (
            other == 0 and proto == PROTO_UDP):
        assert got == (Checksum.OFFLOAD, other, right)
    elif (other, right) in ((0, 0xFFFF), (0xFFFF, 0)) and proto == PROTO_TCP:
        assert got[0] is Checksum.RIGHT  # the two zeros of ones' complement: TCP takes either
    else:
        assert got == (Checksum.WRONG, other, right)


def test_real_loopback_captures_hold_offload_placeholders(real_captures: Path) -> None:
    """Every checksum of the two real loopback captures (273 UDP datagrams, 6 TCP segments; tshark calls
    them all bad, "maybe caused by offload") is its pseudo-header's sum, worked out here with scapy's
    checksum; judep90's (macOS, lo0) IPv4 header checksums are all 0, which tshark calls bad too: mavscope
    gives no checksum note and reads every byte."""
    for name, count in (("ap_sitl_attack1_signed_knownkey.pcap", 273), ("judep90_serial_over_tcp_socat.pcapng", 6)):
        checked = 0
        for pkt in rdpcap(str(real_captures / name)):
            if not (UDP in pkt or (TCP in pkt and bytes(pkt[TCP].payload))):
                continue
            raw = bytes(pkt[IP])
            v6, src, dst, proto, off = layers(raw)
            at = field_at(proto, off)
            assert int.from_bytes(raw[at:at + 2], "big") == pseudo_sum(src, dst, proto, len(raw) - off)
            assert judge(v6, src, dst, proto, raw, off, len(raw))[0] is Checksum.OFFLOAD
            assert pkt[IP].chksum == 0 if name.startswith("judep90") else IP(raw).chksum == pkt[IP].chksum
            checked += 1
        assert checked == count, name
        d = Decapsulator()
        with open_capture(real_captures / name) as reader:
            payloads = [p for rec in reader for p in d.feed(rec)] + d.flush()
        assert not [n for p in payloads for n in p.notes]


# --- UDP: noted, shown -----------------------------------------------------------------------------


def udp_capture(path: Path) -> list[int | None]:
    """Eight datagrams with a HEARTBEAT each: their UDP checksum fields (None: left to scapy)."""
    hb = gcs_heartbeat()
    n = 8 + len(hb)
    placeholder = pseudo_sum(bytes([10, 0, 0, 2]), bytes([10, 0, 0, 1]), PROTO_UDP, n)
    fields: list[int | None] = [None, 0x1234, 0, placeholder, None, 0, 0x4321, placeholder ^ 1]
    pkts = []
    for i, chk in enumerate(fields):
        ip = IPv6(**V6) if i in (4, 5, 6) else IP(**V4)
        udp = UDP(sport=14550, dport=14555) if chk is None else UDP(sport=14550, dport=14555, chksum=chk)
        pkts.append(Ether(**MACS) / ip / udp / hb)
    wrpcap(str(path), pkts)
    return fields


def tshark_checksums(tshark_exe: str, path: Path, proto: str) -> list[tuple[int, str, str]]:
    """(frame, status, calculated) per packet as tshark judges `proto`'s checksum."""
    out = subprocess.run([tshark_exe, "-r", str(path), "-o", f"{proto}.check_checksum:TRUE", "-T", "fields",
                          "-e", "frame.number", "-e", f"{proto}.checksum.status", "-e", f"{proto}.checksum_calculated"],
                         capture_output=True, text=True, check=True).stdout
    return [(int(a), b, c) for a, b, c in (line.split("\t") for line in out.splitlines())]


def test_wrong_udp_checksums_are_noted_where_tshark_finds_them(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                               tshark_exe: str) -> None:
    """The datagrams tshark calls bad (status 0) or illegal (4: 0 over IPv6), less the offload placeholder
    (record 4), are noted, with tshark's calculated checksum as the right one (for record 6, that of record 7,
    the same datagram); every HEARTBEAT is shown (pymavlink's parse of one); both engines give the same."""
    pcap = tmp_path / "udp.pcap"
    udp_capture(pcap)
    judged = tshark_checksums(tshark_exe, pcap, "udp")
    bad = {n: int(calc or "0", 16) for n, status, calc in judged if status in ("0", "4")}
    assert sorted(bad) == [2, 4, 6, 7, 8]  # tshark: 0 over IPv4 is "not present" (3)
    del bad[4]  # scapy's pseudo-header sum, worked out in udp_capture
    bad[6] = bad[7]
    m = mavlink.MAVLink(None)
    want = [(x.get_srcSystem(), x.get_msgId()) for x in m.parse_buffer(gcs_heartbeat())]
    for environ in ENGINES:
        frames = cli.jsonl(pcap, environ=environ)
        assert [(f["sysid"], f["msgid"]) for f in frames] == want * 8
        noted = {f["frame"]: n["message"] for f in frames for n in f.get("notes", ())
                 if n["code"] == "udp-bad-checksum"}
        assert sorted(noted) == sorted(bad), environ
        for record, message in noted.items():
            assert f"0x{bad[record]:04x} is right" in message
        assert "over IPv6" in noted[6]
    status, out, _ = cli("audit", pcap, "--json")
    found = {f["code"]: f["frames"] for f in json.loads(out)["findings"]}
    assert status == 1 and found == {"udp-bad-checksum": [2, 6, 7, 8]}


def test_a_udp_length_past_the_packet_is_noted(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A UDP length 10 bytes past the IP packet's end (Linux drops it as a short packet): a malformed-packet
    note, the frame shown from the bytes there are, on both engines."""
    raw = bytearray(bytes(Ether(**MACS) / IP(**V4) / UDP(sport=14550, dport=14555, chksum=0) / gcs_heartbeat()))
    raw[38:40] = struct.pack("!H", len(raw) - 34 + 10)
    pcap = tmp_path / "long.pcap"
    wrpcap(str(pcap), [Ether(bytes(raw))])
    for environ in ENGINES:
        (frame,) = cli.jsonl(pcap, environ=environ)
        assert [n["code"] for n in frame["notes"]] == ["malformed-packet"]
        assert "runs past the end of its IP packet" in frame["notes"][0]["message"]


def test_wrong_ipv4_header_checksums_are_noted_where_tshark_finds_them(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                       tshark_exe: str) -> None:
    """IPv4 header checksums: scapy's (right), a wrong one, and 0 (what macOS and Windows leave to the NIC),
    on UDP datagrams; then a TCP stream whose SYN is right and whose next segment, a DISARM, has a wrong IP
    header checksum before the ARM: tshark's bad ones (ip.checksum.status 0) less the zeros are noted, with
    tshark's calculated value as the right one; the DISARM is left out (pymavlink's parse of the ARM); both
    engines agree; `audit` reports them."""
    hb, ip = gcs_heartbeat(), IP(**V4)
    pkts = [Ether(**MACS) / IP(**V4, chksum=c) / UDP(sport=14550, dport=14555) / hb for c in (None, 0x1234, 0)]
    pkts += [Ether(**MACS) / ip / TCP(sport=40000, dport=5760, flags="S", seq=999),
             Ether(**MACS) / IP(**V4, chksum=0x4321) / TCP(sport=40000, dport=5760, flags="PA", seq=1000) / gcs_arm(0),
             Ether(**MACS) / ip / TCP(sport=40000, dport=5760, flags="PA", seq=1000) / gcs_arm(1)]
    pcap = tmp_path / "ip.pcap"
    wrpcap(str(pcap), pkts)
    judged = tshark_checksums(tshark_exe, pcap, "ip")
    bad = {n: int(calc, 16) for n, status, calc in judged if status == "0"}
    assert sorted(bad) == [2, 3, 5]
    del bad[3]  # 0: left to the NIC
    m = mavlink.MAVLink(None)
    want = [(x.get_msgId(), getattr(x, "param1", None)) for x in m.parse_buffer(hb * 3 + gcs_arm(1))]
    for environ in ENGINES:
        frames = cli.jsonl(pcap, environ=environ)
        assert [(f["msgid"], f["fields"].get("param1")) for f in frames] == want
        assert [[n["code"] for n in f.get("notes", ())] for f in frames] == [[], ["ip-bad-checksum"], [], []]
        status, out, err = cli("audit", pcap, "--json", environ=environ)
        assert status == 1 and {f["code"]: f["frames"] for f in json.loads(out)["findings"]} == {
            "ip-bad-checksum": [2, 5]}
        assert f"0x{bad[2]:04x} is right" in frames[1]["notes"][0]["message"]
        assert f"record 5: offset {24 + 16 * 5 + sum(len(p) for p in pkts[:4]) + 14}: IPv4 header checksum 0x4321 is " \
            f"wrong (0x{bad[5]:04x} is right)" in err  # (pcap header, record headers, the packets before, Ethernet)


# --- TCP: an insertion is left out ------------------------------------------------------------------


def tcp_packets(wrong: int | None) -> list[Ether]:
    """A SYN, an inserted DISARM at the ARM's sequence number (checksum `wrong`), the ARM, an inserted RST
    (same checksum) and a HEARTBEAT after the ARM: scapy computes the other checksums."""
    a, d, hb = gcs_arm(1), gcs_arm(0), gcs_heartbeat()
    assert len(a) == len(d)
    ip = IP(**V4)

    def seg(flags: str, seq: int, data: bytes = b"", chk: int | None = None) -> Ether:
        t = TCP(sport=40000, dport=5760, flags=flags, seq=seq)
        if chk is not None:
            t.chksum = chk
        return Ether(**MACS) / ip / t / data

    return [seg("S", 999), seg("PA", 1000, d, wrong), seg("PA", 1000, a), seg("R", 1000 + len(a), chk=wrong),
            seg("PA", 1000 + len(a), hb)]


def test_an_inserted_segment_with_a_wrong_checksum_is_left_out(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                tshark_exe: str) -> None:
    """The direction's SYN has a right checksum, so the DISARM and the RST with wrong ones (tshark: bad, and
    its calculated values named) are what the receiver dropped: the stream is the ARM then the HEARTBEAT, as
    pymavlink parses them from the bytes the receiver kept. Both engines; an `audit` finding on records 2
    and 4 (the stream's frames had shown the DISARM, and called the ARM a conflicting retransmission)."""
    pcap = tmp_path / "insertion.pcap"
    wrpcap(str(pcap), tcp_packets(0xBEEF))
    judged = tshark_checksums(tshark_exe, pcap, "tcp")
    bad = {n: int(calc, 16) for n, status, calc in judged if status == "0"}
    assert sorted(bad) == [2, 4]
    m = mavlink.MAVLink(None)
    want = [(x.get_msgId(), getattr(x, "param1", None)) for x in m.parse_buffer(gcs_arm(1) + gcs_heartbeat())]
    for environ in ENGINES:
        frames = cli.jsonl(pcap, environ=environ)
        assert [(f["msgid"], f["fields"].get("param1")) for f in frames] == want == [(76, 1.0), (0, None)]
        assert [f["frame"] for f in frames] == [3, 5]
        status, out, err = cli("audit", pcap, "--json", environ=environ)
        found = {f["code"]: f["frames"] for f in json.loads(out)["findings"]}
        assert status == 1 and found == {"tcp-bad-checksum": [2, 4]}, environ
        for record, right in bad.items():
            assert f"record {record}: " in err and f"(0x{right:04x} is right)" in err


def test_without_a_right_checksum_on_its_direction_a_segment_is_read(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A capture edited without fixing checksums: every segment's is wrong, SYN included. Nothing says which
    are real, so the stream is read as it comes (the DISARM first, as a monitor without checksums reads it:
    pymavlink's parse of the segments' bytes in order, the ARM a conflicting retransmission), each segment
    noted."""
    pcap = tmp_path / "edited.pcap"  # (the inserted RST ends the stream; the HEARTBEAT starts another)
    pkts = tcp_packets(0xBEEF)
    for p in pkts:
        p[TCP].chksum = 0xBEEF
    wrpcap(str(pcap), pkts)
    m = mavlink.MAVLink(None)
    want = [(x.get_msgId(), getattr(x, "param1", None)) for x in m.parse_buffer(gcs_arm(0) + gcs_heartbeat())]
    frames = cli.jsonl(pcap)
    assert [(f["msgid"], f["fields"].get("param1")) for f in frames] == want == [(76, 0.0), (0, None)]
    status, out, _ = cli("audit", pcap, "--json")
    found = {f["code"]: f["frames"] for f in json.loads(out)["findings"]}
    assert status == 1 and found["tcp-bad-checksum"] == [1, 2, 3, 4, 5]


def test_a_datagram_of_64_kib() -> None:
    """A 65,000-byte datagram is judged right, and wrong with one bit flipped, the right value scapy's
    checksum of the flipped datagram."""
    raw = bytes(IP(**V4) / UDP(sport=1, dport=2) / (b"\xa5" * 65000))
    assert judge(False, raw[12:16], raw[16:20], PROTO_UDP, raw, 20, len(raw))[0] is Checksum.RIGHT
    flipped = raw[:-1] + bytes([raw[-1] ^ 1])
    again = IP(flipped)
    del again[UDP].chksum
    verdict, _, right = judge(False, raw[12:16], raw[16:20], PROTO_UDP, flipped, 20, len(flipped))
    assert verdict is Checksum.WRONG and right == IP(bytes(again))[UDP].chksum


@pytest.mark.parametrize("v6", [False, True], ids=["ipv4", "ipv6"])
def test_a_snapped_datagram_is_not_judged(v6: bool) -> None:
    """A record the capture cut short holds too few bytes to judge: no note, the bytes read as captured."""
    from mavscope.capture.base import LINKTYPE_ETHERNET, Record

    raw = bytes(Ether(**MACS) / (IPv6(**V6) if v6 else IP(**V4)) / UDP(sport=14550, dport=14555, chksum=0x1234)
                / gcs_heartbeat())
    d = Decapsulator()
    (p,) = d.feed(Record(1, 0.0, LINKTYPE_ETHERNET, raw[:-3], 0, len(raw)))
    assert not p.notes and p.data == gcs_heartbeat()[:-3]
