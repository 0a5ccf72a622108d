"""802.11 defragmentation (mavscope.transport.air.Fragments): an MSDU sent in fragments is read whole.

A receiver reassembles fragments (IEEE 802.11-2016 10.6), so a packet sent in three fragments reaches the
vehicle; mavscope used to say "not reassembled" and show nothing of it, which let a command pass unseen.
tshark reassembles the same captures (its wlan.defragment, on by default) and decrypts them with the
passphrase: pymavlink's parse of the UDP payload it finds, and the record it finds it in (the last
fragment's), are the expected frames. Where tshark is more lenient than a receiver (fragments out of order,
packet numbers not consecutive, keys or protection mixed: the FragAttacks of 2021, which Linux's mac80211
drops since), the receiver's rule is the expected answer, cited in each test.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.dot11 import Dot11, Dot11QoS, RadioTap
from scapy.packet import Packet, Raw
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_IEEE802_11_RADIOTAP, Record
from mavscope.transport.decap import Decapsulator
from mavscope.transport.wpa import Wpa, wifi_key
from tests.support import wpa as w

KEY = f"wpa-pwd:{w.PASSPHRASE}:{w.SSID}"


def chunks(msdu: bytes, n: int) -> list[bytes]:
    size = -(-len(msdu) // n)
    return [msdu[i:i + size] for i in range(0, len(msdu), size)]


def open_fragments(msdu: bytes, sn: int, n: int = 3, a2: str = w.STA, order: list[int] | None = None) -> list[Packet]:
    """`msdu` in `n` fragments from `a2` to the access point (QoS data, TID 0), in `order`."""
    parts = chunks(msdu, n)
    out = [RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS" + ("+MF" if i < len(parts) - 1 else ""),
                              addr1=w.AP, addr2=a2, addr3=w.AP, SC=sn << 4 | i) / Dot11QoS() / Raw(p)
           for i, p in enumerate(parts)]
    return [out[i] for i in (order or range(len(out)))]


def protected_fragments(msdu: bytes, sn: int, pns: list[int]) -> list[Packet]:
    parts = chunks(msdu, len(pns))
    return [w.ccmp_frame(w.AP, w.STA, sn, pn, p, fragment=i, more=i < len(parts) - 1)
            for i, (p, pn) in enumerate(zip(parts, pns))]


def feed(pkts: list[Packet], keyed: bool = False) -> tuple[list[list], list]:
    dec = Decapsulator(wpa=Wpa((wifi_key(KEY, 1),)) if keyed else None)
    got = [dec.feed(Record(i, i / 1000, LINKTYPE_IEEE802_11_RADIOTAP, bytes(p), 0, len(bytes(p))))
           for i, p in enumerate(pkts, 1)]
    return got, dec.flush()


def codes(got: list) -> list[list[str]]:
    return [[n.code for p in g for n in p.notes] for g in got]


def frames(got: list) -> list[tuple[int, int, int]]:
    """(record, msgid, seq) of each MAVLink frame pymavlink parses from the payloads."""
    return [(p.record, f.get_msgId(), f.get_seq()) for g in got for p in g
            for f in mavlink.MAVLink(None).parse_buffer(p.data) or ()]


def tshark(tshark_exe: str, path: Path) -> list[tuple[int, int, int]]:
    out = subprocess.run([tshark_exe, "-o", "wlan.enable_decryption:TRUE", "-o",
                          f'uat:80211_keys:"wpa-pwd","{w.PASSPHRASE}:{w.SSID}"', "-r", str(path), "-T", "fields",
                          "-e", "frame.number", "-e", "udp.payload"], capture_output=True, text=True, check=True).stdout
    return [(int(n), f.get_msgId(), f.get_seq()) for n, p in (line.split("\t") for line in out.splitlines()) if p
            for f in mavlink.MAVLink(None).parse_buffer(bytes.fromhex(p)) or ()]


ARM = w.mavlink_packet(255, 7, arm=True)  # LLC/SNAP, IP, UDP: a HEARTBEAT and an ARM COMMAND_LONG


def test_an_open_networks_fragments(tmp_path: Path, tshark_exe: str, cli) -> None:  # type: ignore[no-untyped-def]
    pkts = open_fragments(ARM, 5) + open_fragments(w.mavlink_packet(255, 8), 6, n=2)
    path = tmp_path / "frag.pcap"
    wrpcap(str(path), pkts)
    expected = tshark(tshark_exe, path)
    assert [r for r, _, _ in expected] == [3, 3, 5]  # each MSDU at its last fragment
    got, left = feed(pkts)
    assert frames(got) == expected and not any(codes(got)) and not left
    written = tmp_path / "arm.pcap"
    assert cli("read", path, "-Y", "COMMAND_LONG", "-w", written).status == 0  # its three fragments with it
    assert [(f["frame"], f["msgid"]) for f in cli.jsonl(written)] == [(3, 0), (3, 76)]
    for argv in (("read", path, "-T", "jsonl"), ("stats", path, "--json")):
        assert cli(*argv, environ={"MAVSCOPE_PURE": "0"}) == cli(*argv, environ={"MAVSCOPE_PURE": "1"})


def test_protected_fragments(tmp_path: Path, tshark_exe: str) -> None:
    """Each fragment is encrypted on its own, with consecutive packet numbers (12.5.3.4.4)."""
    pkts = [*w.handshake(), *protected_fragments(ARM, 3, [1, 2, 3])]
    path = tmp_path / "wpa_frag.pcap"
    wrpcap(str(path), pkts)
    expected = tshark(tshark_exe, path)
    assert [r for r, _, _ in expected] == [7, 7]
    got, _ = feed(pkts, keyed=True)
    assert frames(got) == expected and not any(codes(got))


def test_what_a_receiver_drops() -> None:
    """mac80211 (ieee80211_rx_h_defragment, with the FragAttacks fixes): fragments in order only, under one
    key with consecutive packet numbers, never protected and plaintext mixed; each such MSDU is dropped,
    said on the fragment that breaks it."""
    _, _, tk2 = w.keys_for(bytes([3]) * 32, bytes([4]) * 32)
    rekey = w.handshake(bytes([3]) * 32, bytes([4]) * 32, replay=3)  # (the station's keys are now tk2, then TK)
    plain_last = RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS", addr1=w.AP, addr2=w.STA, addr3=w.AP,
                                    SC=3 << 4 | 2) / Dot11QoS() / Raw(chunks(ARM, 3)[2])
    cases = {
        "a gap in the packet numbers": protected_fragments(ARM, 3, [1, 2, 4]),
        "a fragment under another key": protected_fragments(ARM, 3, [1, 2, 3])[:2] + rekey
        + [w.ccmp_frame(w.AP, w.STA, 3, 3, chunks(ARM, 3)[2], key=tk2, fragment=2)],
        "plaintext among protected": protected_fragments(ARM, 3, [1, 2, 3])[:2] + [plain_last],
    }
    for name, frags in cases.items():
        got, _ = feed([*w.handshake(), *frags], keyed=True)
        assert not frames(got), name
        said = [c for c in codes(got) if c]
        assert said in ([["wifi-fragment-mixed"]], [["wifi-unprotected"]]), (name, said)
    got, left = feed(open_fragments(ARM, 5, order=[0, 2, 1]))  # fragment 2 before 1: dropped alone
    assert not frames(got) and codes(got) == [[], ["wifi-fragment"], []]
    assert "no fragment before it" in got[1][0].notes[0].message and len(left) == 1  # (the MSDU never completes)
    pkts = [*w.handshake(), *protected_fragments(ARM, 3, [1, 2, 3])]
    stray = RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS+MF", addr1=w.AP, addr2=w.STA, addr3=w.AP,
                               SC=3 << 4 | 1) / Dot11QoS() / Raw(b"injected")
    got, _ = feed([*pkts[:5], stray, *pkts[5:]], keyed=True)  # a plaintext fragment injected in between: it
    assert codes(got)[5] == ["wifi-fragment-mixed"] and [f[:2] for f in frames(got)] == [(8, 0), (8, 76)]  # alone


def test_fragments_never_completed_are_said() -> None:
    """A station reassembles four MSDUs at once (mac80211): a fifth pushes the oldest out; what is held at
    the end of the capture, or longer than 2 s, never completes. Each is said."""
    first_two = open_fragments(ARM, 5)[:2]
    got, left = feed([*first_two, *open_fragments(w.mavlink_packet(255, 8), 6, n=2)])
    assert not any(codes(got)) and [f[2] for f in frames(got)] == [8]
    assert [n.code for p in left for n in p.notes] == ["wifi-fragment"] and "records 1, 2" in left[0].notes[0].message
    starts = [open_fragments(w.mavlink_packet(255, i), 10 + i)[0] for i in range(5)]
    got, left = feed(starts)
    assert codes(got) == [[], [], [], [], ["wifi-fragment"]] and "pushed out" in got[4][0].notes[0].message
    assert len(left) == 4
    dec = Decapsulator()
    late = [dec.feed(Record(i + 1, t, LINKTYPE_IEEE802_11_RADIOTAP, bytes(p), 0, len(bytes(p))))
            for i, (p, t) in enumerate(zip(open_fragments(ARM, 5), (0.0, 0.5, 2.7)))]
    assert not frames(late) and [n.code for p in late[2] for n in p.notes] == ["wifi-fragment"]
    assert "expired" in late[2][0].notes[0].message


def test_group_addressed_and_snapped_fragments() -> None:
    """802.11 fragments only individually addressed frames (10.5): mac80211 drops group-addressed ones; a
    fragment cut by the capture's snap length is not joined with a hole."""
    bcast = [RadioTap() / Dot11(type=2, subtype=8, FCfield="from_DS" + ("+MF" if i == 0 else ""),
                                addr1=w.BROADCAST, addr2=w.AP, addr3=w.STA, SC=5 << 4 | i) / Dot11QoS() / Raw(p)
             for i, p in enumerate(chunks(ARM, 2))]
    got, _ = feed(bcast)
    assert not frames(got) and codes(got) == [["wifi-fragment"], ["wifi-fragment"]]
    frags = [bytes(p) for p in open_fragments(ARM, 5)]
    dec = Decapsulator()
    got = [dec.feed(Record(1, 0.0, LINKTYPE_IEEE802_11_RADIOTAP, frags[0][:-10], 0, len(frags[0])))]
    got += [dec.feed(Record(i, i / 1000, LINKTYPE_IEEE802_11_RADIOTAP, f, 0, len(f))) for i, f in ((2, frags[1]),
                                                                                                  (3, frags[2]))]
    assert not frames(got) and codes(got)[0] == ["wifi-fragment"] and "snap length" in got[0][0].notes[0].message


def test_two_transmitters_interleaved() -> None:
    a = open_fragments(ARM, 5)
    b = open_fragments(w.mavlink_packet(255, 9), 5, a2=w.STA2)
    got, _ = feed([a[0], b[0], a[1], b[1], a[2], b[2]])
    assert [(r, s) for r, _, s in frames(got)] == [(5, 7), (5, 7), (6, 9)] and not any(codes(got))


def test_an_injected_fragment_is_an_audit_finding(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    pkts = [*w.handshake(), *protected_fragments(ARM, 3, [1, 2, 3])]
    stray = RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS+MF", addr1=w.AP, addr2=w.STA, addr3=w.AP,
                               SC=3 << 4 | 1) / Dot11QoS() / Raw(b"injected")
    path = tmp_path / "mixed.pcap"
    wrpcap(str(path), [*pkts[:5], stray, *pkts[5:]])
    status, out, _ = cli("audit", path, "--wifi-key", KEY, "--json")
    assert status == 1 and {f["code"]: f["frames"] for f in json.loads(out)["findings"]} == {"wifi-fragment-mixed": [6]}
    for argv in (("read", path, "-T", "jsonl"), ("audit", path, "--json")):
        assert cli(*argv, "--wifi-key", KEY, environ={"MAVSCOPE_PURE": "0"}) == \
            cli(*argv, "--wifi-key", KEY, environ={"MAVSCOPE_PURE": "1"})
