"""What two reviews found: ways around the checksum rules (mavscope/transport/checksum.py `Directions`), and
false alarms, each made here with scapy. Expected answers as in test_checksum.py: scapy's checksums,
tshark's verdicts where named, pymavlink's parse of the bytes a Linux receiver keeps.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.inet import IP, TCP, UDP, IPOption
from scapy.layers.l2 import Ether
from scapy.utils import checksum, wrpcap

from mavscope.transport.checksum import PROTO_TCP, PROTO_UDP, Checksum, judge
from mavscope.transport.decap import Decapsulator
from tests.support.builders import gcs_arm, gcs_heartbeat
from tests.transport.test_checksum import ENGINES, MACS, V4, pseudo_sum


def insertion(inserted: Ether | bytes) -> list[Ether]:
    """A SYN with right checksums, `inserted` (a DISARM at the ARM's sequence number, in a packet a Linux
    receiver drops), the ARM, a HEARTBEAT: scapy computes every other checksum."""
    ip = IP(**V4)

    def seg(flags: str, seq: int, data: bytes = b"") -> Ether:
        return Ether(**MACS) / ip / TCP(sport=40000, dport=5760, flags=flags, seq=seq) / data

    a = gcs_arm(1)
    return [seg("S", 999), Ether(bytes(inserted)), seg("PA", 1000, a), seg("PA", 1000 + len(a), gcs_heartbeat())]


def disarm_segment(**ip: object) -> Ether:
    return Ether(**MACS) / IP(**V4, **ip) / TCP(sport=40000, dport=5760, flags="PA", seq=1000) / gcs_arm(0)


def refreshed(pkt: Ether, edit: slice, value: bytes) -> bytes:
    """`pkt` with bytes `edit` of its IPv4 header replaced and the header checksum made right again (scapy)."""
    raw = bytearray(bytes(pkt))
    raw[edit] = value
    raw[24:26] = b"\0\0"
    raw[24:26] = struct.pack("!H", checksum(bytes(raw[14:34])))
    return bytes(raw)


def _placeholder_disarm() -> Ether:
    seg = disarm_segment()
    raw = bytes(seg[IP])
    seg[TCP].chksum = pseudo_sum(raw[12:16], raw[16:20], PROTO_TCP, len(raw) - 20)
    return seg


def _fragments(edit: Callable[[bytes], bytes], payload: bytes | None = None) -> list[Ether]:
    """The inserted segment (a DISARM, or `payload` in its place) in IPv4 fragments of 24 bytes as scapy cuts
    them, each edited by `edit` (its IPv4 header bytes, from the IP header on)."""
    from scapy.layers.inet import fragment

    seg = disarm_segment(id=99) if payload is None else Ether(**MACS) / IP(**V4, id=99) / TCP(
        sport=40000, dport=5760, flags="PA", seq=1000) / payload
    if payload is not None:
        raw = bytes(seg[IP])
        seg[TCP].chksum = pseudo_sum(raw[12:16], raw[16:20], PROTO_TCP, len(raw) - 20)
    eth = bytes(Ether(**MACS, type=0x0800))
    return [Ether(eth + edit(bytes(f))) for f in fragment(IP(bytes(seg[IP])), fragsize=24)]


def _header(raw: bytes, at: slice, value: bytes, fix: bool = True) -> bytes:
    """IPv4 packet `raw` with header bytes `at` replaced, its header checksum made right again (scapy) if `fix`."""
    out = bytearray(raw)
    out[at] = value
    if fix:
        out[10:12] = b"\0\0"
        out[10:12] = struct.pack("!H", checksum(bytes(out[:20])))
    return bytes(out)


def _tunnel(outer: str) -> list[Ether]:
    """The inserted segment inside a GRE packet whose outer IPv4 header checksum is 0, or a VXLAN datagram
    whose UDP checksum is the pseudo-header's sum (scapy's checksum): a sender's placeholders, which a
    receiver on the direction (whose checksums are right) never sees."""
    from scapy.layers.l2 import GRE
    from scapy.layers.vxlan import VXLAN

    inner = disarm_segment()
    if outer == "gre":
        return [Ether(**MACS) / IP(src="1.1.1.1", dst="2.2.2.2", chksum=0) / GRE() / inner[IP]]
    pkt = Ether(**MACS) / IP(src="1.1.1.1", dst="2.2.2.2") / UDP(sport=5000, dport=4789) / VXLAN(vni=1) / inner
    raw = bytes(pkt[IP])
    pkt[UDP].chksum = pseudo_sum(raw[12:16], raw[16:20], PROTO_UDP, len(raw) - 20)
    return [pkt]


INSERTIONS: dict[str, Callable[[], list[Ether]]] = {
    # tshark: the TCP checksum bad ("maybe offload"): the pseudo-header's sum, worked out with scapy
    "tcp-placeholder": lambda: [_placeholder_disarm()],
    # tshark: the IPv4 header checksum bad (0); Linux checks every header
    "ip-checksum-0": lambda: [disarm_segment(chksum=0)],
    # Linux: tot_len < ihl, or more than the packet holds: dropped in ip_rcv_core
    "total-length-0": lambda: [Ether(refreshed(disarm_segment(), slice(16, 18), b"\0\0"))],
    "total-length-long": lambda: [Ether(refreshed(disarm_segment(), slice(16, 18),
                                                  struct.pack("!H", len(bytes(disarm_segment()[IP])) + 2)))],
    # fragments: with a wrong header checksum (tshark: bad; Linux drops them before reassembly), with a header
    # checksum of 0 or a total length of 0 (on this direction, what its receiver dropped), and a 2,000-byte
    # segment with the placeholder (a receiver's merge is never reassembled from fragments)
    "fragments-wrong-header": lambda: _fragments(lambda f: _header(f, slice(10, 12), b"\x13\x57", fix=False)),
    "fragments-header-0": lambda: _fragments(lambda f: _header(f, slice(10, 12), b"\0\0", fix=False)),
    "fragments-total-length-0": lambda: _fragments(lambda f: _header(f, slice(2, 4), b"\0\0")),
    "fragments-big-placeholder": lambda: _fragments(lambda f: f, gcs_arm(0) * 45),
    # Linux's ip_options_compile: an option whose length (1) is under 2 (tshark: an expert error on it)
    "ip-option-malformed": lambda: [disarm_segment(options=[IPOption(b"\x83\x01\x00\x00")])],
    "ip-option-pointer": lambda: [disarm_segment(options=[IPOption(b"\x07\x07\x02\x00\x00\x00\x00\x00")])],
    # tunnels: the outer packet with a sender's placeholder
    "gre-outer-header-0": lambda: _tunnel("gre"),
    "vxlan-outer-placeholder": lambda: _tunnel("vxlan"),
}


@pytest.mark.parametrize("kind", sorted(INSERTIONS))
def test_an_insertion_a_linux_receiver_drops_is_left_out(cli, tmp_path: Path, kind: str) -> None:  # type: ignore[no-untyped-def]
    """Two reviews' bypasses of the insertion rule: each inserted DISARM is in a packet a Linux receiver drops,
    on a direction that has carried right checksums (its SYN): the stream is the ARM and the HEARTBEAT, as
    pymavlink parses the bytes the receiver kept, on both engines, and the records are noted. Without the rule
    the DISARM is the stream and the ARM a tcp-conflict."""
    inserted = INSERTIONS[kind]()
    base = insertion(b"")
    pkts = base[:1] + inserted + base[2:]
    pcap = tmp_path / f"{kind}.pcap"
    wrpcap(str(pcap), pkts)
    m = mavlink.MAVLink(None)
    want = [(x.get_msgId(), getattr(x, "param1", None)) for x in m.parse_buffer(gcs_arm(1) + gcs_heartbeat())]
    for environ in ENGINES:
        frames = cli.jsonl(pcap, environ=environ)
        assert [(f["msgid"], f["fields"].get("param1")) for f in frames] == want, (kind, environ)
        _, out, err = cli("audit", pcap, "--json", environ=environ)
        assert "tcp-conflict" not in {f["code"] for f in json.loads(out)["findings"]}
        assert f"record {len(inserted) + 1}: " in err


def test_a_receivers_merge_keeps_the_placeholder_and_is_read(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Linux's GRO leaves the pseudo-header's sum on the segments it merged (tcp_gro_complete), in a capture
    taken on the receiver: a segment larger than one Ethernet frame holds, and than any with a right
    checksum on its direction, is read without a note; the same placeholder on a small one is not."""
    hb = gcs_heartbeat()
    big = hb * 80  # 1,680 bytes: two segments' worth
    ip = IP(**V4)

    def seg(flags: str, seq: int, data: bytes, placeholder: bool = False) -> Ether:
        t = TCP(sport=40000, dport=5760, flags=flags, seq=seq)
        if placeholder:
            raw = bytes(ip / t / data)
            t.chksum = pseudo_sum(raw[12:16], raw[16:20], PROTO_TCP, len(raw) - 20)
        return Ether(**MACS) / ip / t / data

    pcap = tmp_path / "gro.pcap"
    wrpcap(str(pcap), [seg("S", 999, b""), seg("PA", 1000, hb), seg("PA", 1000 + len(hb), big, True),
                       seg("PA", 1000 + len(hb) + len(big), hb, True)])
    frames = cli.jsonl(pcap)
    assert len(frames) == 1 + 80 and not any(f.get("notes") for f in frames)
    status, out, _ = cli("audit", pcap, "--json")
    assert {f["code"]: f["frames"] for f in json.loads(out)["findings"]} == {"tcp-bad-checksum": [4]}


def test_a_flood_of_directions_forgets_the_least_recently_confirmed() -> None:
    """The directions with right checksums are bounded; the one confirmed last stays, the oldest goes."""
    from mavscope.endpoint import Endpoint
    from mavscope.transport.checksum import Directions

    ends = [Endpoint("10.0.0.1", p) for p in range(6)]
    dirs = Directions(limit=3)
    for e in ends[:3]:
        dirs.right((e, ends[5]), 10)
    dirs.right((ends[0], ends[5]), 10)  # confirmed again: the most recent
    dirs.right((ends[3], ends[5]), 10)
    wrong = (Checksum.WRONG, 1, 2)
    assert dirs.fate((ends[0], ends[5]), 10, None, *wrong, False, None)[1] is True  # still known: left out
    assert dirs.fate((ends[1], ends[5]), 10, None, *wrong, False, None)[1] is False  # forgotten: read


def test_windows_large_send_placeholder_is_not_judged() -> None:
    """Windows' large send offload (and OpenBSD's TSO) leave the pseudo-header's sum without the length."""
    raw = bytes(IP(**V4) / TCP(sport=1, dport=2) / (b"x" * 3000))
    at = 20 + 16
    field = pseudo_sum(raw[12:16], raw[16:20], PROTO_TCP, 0)
    raw = raw[:at] + struct.pack("!H", field) + raw[at + 2:]
    assert judge(False, raw[12:16], raw[16:20], PROTO_TCP, raw, 20, len(raw))[0] is Checksum.OFFLOAD


def test_a_header_note_survives_a_cut_short_udp_header() -> None:
    """A wrong IPv4 header checksum on a packet whose UDP header is cut short: both notes."""
    from mavscope.capture.base import LINKTYPE_ETHERNET, Record

    raw = bytearray(bytes(Ether(**MACS) / IP(**V4, chksum=0x1234, proto=17) / b"\x01\x02\x03"))
    (p,) = Decapsulator().feed(Record(1, 0.0, LINKTYPE_ETHERNET, bytes(raw), 0, len(raw)))
    assert [n.code for n in p.notes] == ["ip-bad-checksum", "malformed-packet"]


def test_a_right_header_checksum_of_0_is_right(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Once in 65,535 headers the right IPv4 header checksum is 0x0000 (scapy: an IP id found for it): on a
    checked direction that segment is read like any other, with no note."""
    ident = next(i for i in range(65536) if IP(bytes(IP(**V4, id=i) / TCP(sport=40000, dport=5760, flags="PA",
                                                                               seq=1000) / gcs_arm(1))).chksum == 0)
    a = gcs_arm(1)
    ip = IP(**V4)
    pkts = [Ether(**MACS) / ip / TCP(sport=40000, dport=5760, flags="S", seq=999),
            Ether(**MACS) / IP(**V4, id=ident) / TCP(sport=40000, dport=5760, flags="PA", seq=1000) / a,
            Ether(**MACS) / ip / TCP(sport=40000, dport=5760, flags="PA", seq=1000 + len(a)) / gcs_heartbeat()]
    assert bytes(pkts[1])[24:26] == b"\0\0"
    pcap = tmp_path / "zero.pcap"
    wrpcap(str(pcap), pkts)
    for environ in ENGINES:
        frames = cli.jsonl(pcap, environ=environ)
        assert [f["msgid"] for f in frames] == [76, 0] and not any(f.get("notes") for f in frames)
        assert cli("audit", pcap, environ=environ).status == 0


def test_a_new_connection_on_a_loopback_starts_unknown(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """On a loopback the kernel's own RST has a right checksum while the connections' segments hold
    placeholders: a later connection on the same 4-tuple, all placeholders, is read whole, with no note."""
    hb = gcs_heartbeat()
    lo = {"src": "127.0.0.1", "dst": "127.0.0.1"}

    def seg(flags: str, seq: int, data: bytes = b"", placeholder: bool = True) -> Ether:
        t = TCP(sport=40000, dport=5760, flags=flags, seq=seq)
        if placeholder:
            raw = bytes(IP(**lo) / t / data)
            t.chksum = pseudo_sum(raw[12:16], raw[16:20], PROTO_TCP, len(raw) - 20)
        return Ether(**MACS) / IP(**lo) / t / data

    pcap = tmp_path / "reuse.pcap"
    wrpcap(str(pcap), [seg("S", 10), seg("R", 11, placeholder=False), seg("S", 5000), seg("PA", 5001, hb),
                       seg("PA", 5001 + len(hb), hb)])
    frames = cli.jsonl(pcap)
    assert [f["frame"] for f in frames] == [4, 5] and not any(f.get("notes") for f in frames)


def test_a_large_send_with_no_length_is_read(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Windows' LSOv2 gives its NIC a packet larger than a frame with IPv4 total length 0 (a sender's capture):
    not a length that lies; the frames in it are read (pymavlink's parse of its payload)."""
    payload = gcs_heartbeat() * 100
    raw = bytearray(bytes(Ether(**MACS) / IP(**V4) / UDP(sport=14550, dport=14555, chksum=0) / payload))
    raw[16:18] = b"\0\0"
    pcap = tmp_path / "lso.pcap"
    wrpcap(str(pcap), [Ether(bytes(raw))])
    m = mavlink.MAVLink(None)
    for environ in ENGINES:
        frames = cli.jsonl(pcap, environ=environ)
        assert len(frames) == len(m.parse_buffer(payload)) == 100
        assert not {n["code"] for f in frames for n in f.get("notes", ())} & {"malformed-packet", "udp-bad-checksum"}


def test_a_problem_line_shows_the_offset_unless_the_message_names_it() -> None:
    from mavscope.notes import note, problem_line

    assert problem_line("record 2", note("tcp-bad-checksum", "TCP checksum 0x1449 is wrong", 144)) == \
        "record 2: offset 144: TCP checksum 0x1449 is wrong"
    assert problem_line("record 2", note("tcp-gap", "at offset 144: gone", 144)) == "record 2: at offset 144: gone"


def test_ipv4_options_that_parse_are_read(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Options that parse (a NOP and a router alert; a record-route with its pointer right): the packet's
    frames are read on both engines (scapy builds the options, pymavlink parses the payload)."""
    options = [IPOption(b"\x01"), IPOption(b"\x94\x04\x00\x00"), IPOption(b"\x07\x07\x04\x00\x00\x00\x00")]
    pkt = Ether(**MACS) / IP(**V4, options=options) / UDP(sport=14550, dport=14555) / gcs_heartbeat()
    assert len(bytes(pkt[IP])) - len(bytes(pkt[UDP])) == 32
    pcap = tmp_path / "options.pcap"
    wrpcap(str(pcap), [pkt])
    for environ in ENGINES:
        (frame,) = cli.jsonl(pcap, environ=environ)
        assert frame["msgid"] == 0 and not frame.get("notes")
