"""802.11 and radiotap link types (mavscope.transport.wifi): MAVLink in monitor-mode Wi-Fi captures.

The frames are scapy's (RadioTap, Dot11, Dot11QoS, LLC, SNAP); the MAVLink frames expected in each are
pymavlink's parse of the UDP payload it carries, and tshark (with pymavlink's Lua dissector) finds the same
frames in the same records. What is not decoded (a protected frame, an A-MSDU, a frame
whose FCS failed) is one note on its record, as the layouts in IEEE 802.11-2016 section 9.2 and radiotap.org
say of each.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.dot11 import Dot11, Dot11FCS, Dot11QoS, RadioTap
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import LLC, SNAP
from scapy.packet import Packet, Raw
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_IEEE802_11, LINKTYPE_IEEE802_11_RADIOTAP, Record
from mavscope.transport.decap import Decapsulator
from tests.support.builders import gcs_arm, gcs_heartbeat

AP, STA = "02:00:00:00:00:01", "02:00:00:00:00:02"


FRAMES = gcs_heartbeat() + gcs_arm(1)  # a ground station's HEARTBEAT and ARM, as pymavlink packs them


def ip() -> Packet:
    """IP and UDP with their lengths set, so that bytes after them (an FCS) are not theirs."""
    n = len(FRAMES)
    return IP(src="192.168.4.2", dst="192.168.4.1", len=28 + n) / UDP(sport=14550, dport=14555, len=8 + n) / \
        FRAMES


def data(fc: str = "to_DS", subtype: int = 0) -> Packet:
    return Dot11(type=2, subtype=subtype, FCfield=fc, addr1=AP, addr2=STA, addr3=AP, addr4=STA if "from_DS" in fc
                 else None)


READABLE = {  # what each readable frame is: the frames in it are pymavlink's parse of FRAMES
    "data": RadioTap() / data() / LLC() / SNAP() / ip(),
    "qos data": RadioTap() / data(subtype=8) / Dot11QoS() / LLC() / SNAP() / ip(),
    "four addresses (a mesh or WDS hop)": RadioTap() / data("to_DS+from_DS") / LLC() / SNAP() / ip(),
    "qos with HT control (order bit)": RadioTap() / data("to_DS+order", 8) / Dot11QoS() / Raw(bytes(4)) / LLC()
    / SNAP() / ip(),
    "radiotap with TSFT and Flags (FCS present, good)": RadioTap(present="TSFT+Flags", mac_timestamp=5, Flags="FCS")
    / Dot11FCS(type=2, FCfield="to_DS", addr1=AP, addr2=STA, addr3=AP) / LLC() / SNAP() / ip(),  # (scapy's FCS)
}
UNREADABLE = {  # (frame, the code of its one note)
    "protected": (RadioTap() / data("to_DS+protected") / Raw(bytes(90)), "wifi-undecoded"),
    "bad FCS": (RadioTap(present="Flags", Flags="FCS+badFCS") / data() / LLC() / SNAP() / ip(), "wifi-bad-fcs"),
}
SILENT = {"beacon": RadioTap() / Dot11(type=0, subtype=8) / Raw(b"beacon"),
          "null data": RadioTap() / data(subtype=4), "not snap": RadioTap() / data() / Raw(b"\x01\x02\x03")}


def pymavlink_frames() -> list[tuple[int, int, int]]:
    return [(f.get_srcSystem(), f.get_srcComponent(), f.get_msgId())
            for f in mavlink.MAVLink(None).parse_buffer(FRAMES)]


def feed(pkt: Packet, linktype: int = LINKTYPE_IEEE802_11_RADIOTAP) -> list:
    raw = bytes(pkt)
    return Decapsulator().feed(Record(1, 1.0, linktype, raw, 0, len(raw)))


@pytest.mark.parametrize("name", READABLE)
def test_data_frames_carry_their_udp(name: str) -> None:
    out = feed(READABLE[name])
    assert len(out) == 1 and out[0].data == FRAMES and not out[0].notes
    assert (str(out[0].src), str(out[0].dst)) == ("192.168.4.2:14550", "192.168.4.1:14555")
    bare = feed(READABLE[name][Dot11], LINKTYPE_IEEE802_11)  # link type 105: the same frame, no radio header
    assert bare[0].data == FRAMES


def amsdu(*packets: bytes, radio: Packet | None = None, fcs: bool = False) -> Packet:
    """A QoS data frame whose body is an A-MSDU of `packets` (IEEE 802.11-2016 9.3.2.2.2, by hand: DA, SA,
    a big-endian length, LLC/SNAP and the packet, padded to 4 bytes but the last), then its FCS if `fcs`."""
    body = b""
    for i, pkt in enumerate(packets):
        msdu = bytes(LLC() / SNAP(code=0x0800)) + pkt
        sub = bytes.fromhex(AP.replace(":", "") + STA.replace(":", "")) + len(msdu).to_bytes(2, "big") + msdu
        body += sub + (bytes(-len(sub) % 4) if i + 1 < len(packets) else b"")
    frame = bytes(data(subtype=8) / Dot11QoS(A_MSDU_Present=1) / Raw(body))
    return (radio or RadioTap()) / Raw(frame + (zlib.crc32(frame).to_bytes(4, "little") if fcs else b""))


def test_radiotap_padding_and_fcs() -> None:
    """radiotap's Flags: 0x20, the 802.11 header is padded to 4 bytes (a 26-byte QoS header, then 2 bytes);
    0x10, the frame ends with its 4-byte FCS, which is no A-MSDU subframe (tshark reads both so)."""
    padded = RadioTap(present="Flags", Flags="pad") / data(subtype=8) / Dot11QoS() / Raw(b"\x00\x00") / LLC() \
        / SNAP() / ip()
    assert [p.data for p in feed(padded)] == [FRAMES]
    with_fcs = amsdu(bytes(ip()), radio=RadioTap(present="Flags", Flags="FCS"), fcs=True)
    out = feed(with_fcs)
    assert [p.data for p in out] == [FRAMES] and not out[0].notes


def test_an_amsdu_carries_each_of_its_packets() -> None:
    other = IP(src="192.168.4.3", dst="192.168.4.1") / UDP(sport=14551, dport=14555) / FRAMES[:21]
    out = feed(amsdu(bytes(ip()), bytes(other)))
    assert [(p.data, str(p.src)) for p in out] == [(FRAMES, "192.168.4.2:14550"),
                                                  (FRAMES[:21], "192.168.4.3:14551")]
    cut = bytes(amsdu(bytes(ip()), bytes(other)))[:-10]
    out = Decapsulator().feed(Record(1, 1.0, LINKTYPE_IEEE802_11_RADIOTAP, cut, 0, len(cut)))
    assert out[0].data == FRAMES and [n.code for n in out[0].notes] == ["malformed-packet"]
    assert "A-MSDU subframe of 57 bytes cut short" in out[0].notes[0].message  # 8 + 20 + 8 + 21


@pytest.mark.parametrize("name", UNREADABLE)
def test_frames_not_decoded_are_one_note(name: str) -> None:
    pkt, code = UNREADABLE[name]
    out = feed(pkt)
    assert len(out) == 1 and not out[0].data and [n.code for n in out[0].notes] == [code]


@pytest.mark.parametrize("name", SILENT)
def test_frames_without_ip_are_passed_over(name: str) -> None:
    assert feed(SILENT[name]) == []


def every_kind(path: Path) -> tuple[Path, list[tuple[int, int, int, int]]]:
    """A pcap of every frame above, and the (record, sysid, compid, msgid) of the frames pymavlink parses from
    the readable ones' UDP payloads (the A-MSDU's second packet is the HEARTBEAT alone)."""
    other = IP(src="192.168.4.3", dst="192.168.4.1") / UDP(sport=14551, dport=14555) / FRAMES[:21]
    pkts = [*READABLE.values(), amsdu(bytes(ip()), bytes(other)), *(p for p, _ in UNREADABLE.values()),
            *SILENT.values()]
    wrpcap(str(path), pkts)
    expected = [(n, *f) for n in range(1, len(READABLE) + 2) for f in pymavlink_frames()]
    return path, expected + [(len(READABLE) + 1, *pymavlink_frames()[0])]


def test_read_and_both_engines(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """`read` shows pymavlink's frames in every readable record and notes the others; both engines give
    the same output."""
    pcap, expected = every_kind(tmp_path / "wifi.pcap")
    got = cli.jsonl(pcap)
    assert [(f["frame"], f["sysid"], f["compid"], f["msgid"]) for f in got] == expected
    err = cli("read", pcap, "-q").err
    assert err.count("not decrypted") == 1 and err.count("failed its FCS check") == 1
    for argv in (("read", pcap, "-T", "jsonl"), ("stats", pcap, "--json")):
        assert cli(*argv, environ={"MAVSCOPE_PURE": "0"}) == cli(*argv, environ={"MAVSCOPE_PURE": "1"})


def test_tshark_finds_the_same_frames(tmp_path: Path, tshark_exe: str, lua_dissector: Path) -> None:
    from tests.support import tshark

    pcap, expected = every_kind(tmp_path / "wifi.pcap")
    theirs = [(f.frame, f.sysid, f.compid, f.msgid)
              for f in tshark.run_lua_dissector(tshark_exe, lua_dissector, pcap, {14555}).frames()
              if f.frame <= len(READABLE) + 1]  # (tshark dissects the bad-FCS frame too: the radio dropped it)
    assert theirs == expected


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.binary(max_size=120), st.sampled_from([LINKTYPE_IEEE802_11, LINKTYPE_IEEE802_11_RADIOTAP]))
def test_any_bytes_never_raise(raw: bytes, linktype: int) -> None:
    Decapsulator().feed(Record(1, 1.0, linktype, raw, 0, len(raw)))


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.integers(0, 200), st.binary(min_size=1, max_size=4))
def test_cut_frames_never_raise(cut: int, junk: bytes) -> None:
    for pkt in [*READABLE.values(), *(p for p, _ in UNREADABLE.values())]:
        raw = bytes(pkt)[:cut] + junk
        Decapsulator().feed(Record(1, 1.0, LINKTYPE_IEEE802_11_RADIOTAP, raw, 0, len(raw)))


def test_a_wrong_fcs_is_what_tshark_calls_bad(tmp_path: Path, tshark_exe: str) -> None:
    """Where radiotap says the FCS is there and the driver did not flag it, the FCS is checked as the radio
    did (CRC-32 over the 802.11 frame): a bit flipped in the air drops the frame. tshark's check
    (`wlan.check_checksum`) is the reference; a snapped record, whose last bytes are no FCS, is not checked."""
    import subprocess

    good = bytes(READABLE["radiotap with TSFT and Flags (FCS present, good)"])
    flipped = bytearray(good)
    flipped[-10] ^= 0x01  # in the UDP payload
    fcs_flipped = good[:-1] + bytes((good[-1] ^ 0x80,))
    pcap = tmp_path / "fcs.pcap"
    wrpcap(str(pcap), [RadioTap(good), RadioTap(bytes(flipped)), RadioTap(fcs_flipped)])
    out = subprocess.run([tshark_exe, "-o", "wlan.check_checksum:TRUE", "-r", str(pcap), "-T", "fields", "-e",
                          "wlan.fcs.status"], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["1", "0", "0"]  # good, bad, bad
    got = [Decapsulator().feed(Record(1, 1.0, LINKTYPE_IEEE802_11_RADIOTAP, raw, 0, len(raw)))
           for raw in (good, bytes(flipped), fcs_flipped)]
    assert [[n.code for p in g for n in p.notes] for g in got] == [[], ["wifi-bad-fcs"], ["wifi-bad-fcs"]]
    assert "FCS 0x" in got[1][0].notes[0].message
    snapped = good[:-20]
    out2 = Decapsulator().feed(Record(1, 1.0, LINKTYPE_IEEE802_11_RADIOTAP, snapped, 0, len(good)))
    assert "wifi-bad-fcs" not in [n.code for p in out2 for n in p.notes]
