"""802.11 duplicate detection (mavscope.transport.wifi.Retries): a retransmission the receiver discards.

A monitor-mode capture holds every copy a radio sent; when an ACK is lost the sender sends the frame again
with the Retry bit set, and the receiver discards the copy (IEEE 802.11-2016 10.3.2.14: a frame with the
Retry bit that matches its cache's <Address 2, sequence number, fragment number>, kept per TID for QoS data).
The expected answers: tshark's own retransmission analysis (`wlan.analysis.retransmission`, with
`wlan.retransmitted:FALSE`, its switch for it) where its rule and the standard's agree, and the standard's
rule, worked out by hand in each case, where tshark's is coarser (it keys on BSSID and source alone, without
the receiver or the TID, and ignores the Retry bit). The frames shown are pymavlink's parse of the UDP
payloads of the frames kept.
"""

from __future__ import annotations

import json
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.dot11 import Dot11, Dot11QoS, RadioTap
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import LLC, SNAP
from scapy.packet import Packet, Raw
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_IEEE802_11_RADIOTAP, Record
from mavscope.transport.air import Retries
from mavscope.transport.decap import Decapsulator
from tests.support.builders import gcs_heartbeat, mav2

AP, STA, STA2 = "02:00:00:00:00:01", "02:00:00:00:00:02", "02:00:00:00:00:03"


def frame(a1: str, a2: str, sn: int, seq: int, retry: bool = False, tid: int | None = None,
          flags: str = "") -> Packet:
    """A data frame from `a2` to `a1` with 802.11 sequence number `sn`, carrying the HEARTBEAT of MAVLink
    sequence `seq` in UDP."""
    fc = ("to_DS" if a1 == AP else "from_DS") + ("+retry" if retry else "") + flags
    d = Dot11(type=2, subtype=8 if tid is not None else 0, FCfield=fc, addr1=a1, addr2=a2, addr3=AP, SC=sn << 4)
    if tid is not None:
        d = d / Dot11QoS(TID=tid)
    body = gcs_heartbeat(mav2(255, 190, seq))
    return RadioTap() / d / LLC() / SNAP() / IP(src="192.168.4.2", dst="192.168.4.1") / UDP(
        sport=14550, dport=14555) / body


# tshark and the standard agree on these: (frame, a retransmission the receiver discards)
AGREED = [
    (frame(AP, STA, 10, 0), False),
    (frame(AP, STA, 10, 0, retry=True), True),  # the ACK of the frame before was lost
    (frame(AP, STA, 11, 1, retry=True), False),  # a retry whose first copy the monitor missed: read
    (frame(AP, STA, 30, 2), False),
    (frame(AP, STA2, 5, 3), False),  # another station in between
    (frame(AP, STA, 30, 2, retry=True), True),  # still the last from STA to AP
    (frame(AP, STA, 30, 2, retry=True), True),  # and again
]


def seqs(payloads: list) -> list[int]:
    return [f.get_seq() for p in payloads for f in mavlink.MAVLink(None).parse_buffer(p.data) or ()]


def feed_all(pkts: list[Packet], dec: Decapsulator | None = None) -> list[list]:
    dec = dec or Decapsulator()
    out = []
    for i, pkt in enumerate(pkts, 1):
        raw = bytes(pkt)
        out.append(dec.feed(Record(i, float(i), LINKTYPE_IEEE802_11_RADIOTAP, raw, 0, len(raw))))
    return out


def codes(got: list) -> list[str]:
    return [n.code for p in got for n in p.notes]


def test_retransmissions_as_tshark_finds_them(tmp_path: Path, tshark_exe: str) -> None:
    import subprocess

    pcap = tmp_path / "retry.pcap"
    wrpcap(str(pcap), [p for p, _ in AGREED])
    lines = subprocess.run([tshark_exe, "-o", "wlan.retransmitted:FALSE", "-r", str(pcap), "-T", "fields", "-e",
                            "wlan.analysis.retransmission"], capture_output=True, text=True, check=True).stdout
    theirs = [bool(line.strip()) for line in lines.splitlines()]
    assert theirs == [dup for _, dup in AGREED]  # the reference agrees with the cases as written
    got = feed_all([p for p, _ in AGREED])
    assert [codes(g) == ["wifi-retry"] for g in got] == theirs
    kept = [p for (_, dup), g in zip(AGREED, got) for p in g if not dup]
    assert seqs(kept) == [0, 1, 2, 3]  # pymavlink: one HEARTBEAT each, none twice


def test_the_standards_cache_is_per_receiver_and_tid() -> None:
    """Each of these repeats the sequence number of the frame before it from the same transmitter, which
    tshark calls a retransmission; the standard's receiver reads each (another TID's cache, another
    receiver's cache, no Retry bit)."""
    pkts = [frame(AP, STA, 12, 0, tid=0), frame(AP, STA, 12, 1, retry=True, tid=5),  # another TID
            frame(STA, AP, 20, 2, tid=0), frame(STA2, AP, 20, 3, retry=True, tid=0),  # another receiver
            frame(AP, STA, 40, 4), frame(AP, STA, 40, 5)]  # no Retry bit: a new frame, whatever its number
    got = feed_all(pkts)
    assert all(not codes(g) for g in got)
    assert seqs([p for g in got for p in g]) == [0, 1, 2, 3, 4, 5]
    # and within one TID, a QoS retransmission is discarded
    assert codes(feed_all([frame(AP, STA, 12, 0, tid=3), frame(AP, STA, 12, 0, retry=True, tid=3)])[1]) == [
        "wifi-retry"]


def test_a_block_ack_retransmission_after_later_frames() -> None:
    """Under a block ack agreement the receiver acknowledges an A-MPDU's frames in one bitmap, and resends
    only those it missed: frame 11's retransmission comes after 12 and 13, and a receiver that had it (the
    monitor did) discards it from its scoreboard (802.11-2016 10.3.2.14.3, 10.24.7). tshark's rule (the last
    number only) would show it again."""
    pkts = [frame(AP, STA, n, n - 10, tid=0) for n in (10, 11, 12, 13)] + [frame(AP, STA, 11, 1, retry=True, tid=0)]
    got = feed_all(pkts)
    assert [codes(g) for g in got] == [[], [], [], [], ["wifi-retry"]]
    assert seqs([p for g in got for p in g]) == [0, 1, 2, 3]


def test_a_counter_started_over_starts_the_cache_over() -> None:
    """A station that associates again numbers its frames from 0 again: a retransmission of its new frame
    numbered as an old one was is no conflict (the old number is far behind the newest)."""
    pkts = [frame(AP, STA, 4, 0), frame(AP, STA, 2000, 1), frame(AP, STA, 0, 2), frame(AP, STA, 4, 3),
            frame(AP, STA, 4, 3, retry=True)]
    got = feed_all(pkts)
    assert [codes(g) for g in got] == [[], [], [], [], ["wifi-retry"]]
    assert seqs([p for g in got for p in g]) == [0, 1, 2, 3]


def test_a_retransmission_with_another_body_is_a_conflict(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The receiver keeps the first copy (it discards the repeat unread); a repeat with other bytes is no
    radio's own: a warning, and an audit finding naming its record."""
    pkts = [frame(AP, STA, 7, 0), frame(AP, STA, 7, 9, retry=True), frame(AP, STA, 8, 1)]
    got = feed_all(pkts)
    assert codes(got[1]) == ["wifi-retry-conflict"] and seqs([p for g in got for p in g]) == [0, 1]
    pcap = tmp_path / "conflict.pcap"
    wrpcap(str(pcap), pkts)
    assert [f["seq"] for f in cli.jsonl(pcap)] == [0, 1]
    status, out, _ = cli("audit", pcap, "--json")
    found = {f["code"]: f["frames"] for f in json.loads(out)["findings"]}
    assert status == 1 and found == {"wifi-retry-conflict": [2]}
    for argv in (("read", pcap, "-T", "jsonl"), ("stats", pcap, "--json"), ("audit", pcap, "--json")):
        assert cli(*argv, environ={"MAVSCOPE_PURE": "0"}) == cli(*argv, environ={"MAVSCOPE_PURE": "1"})


def test_stats_counts_no_duplicate(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Before, the retransmissions' HEARTBEATs were counted again: duplicates in the Links table."""
    pcap = tmp_path / "retry.pcap"
    wrpcap(str(pcap), [p for p, _ in AGREED])
    (link,) = cli.json("stats", pcap)["links"]
    assert (link["received"], link["duplicates"], link["lost"]) == (4, 0, 0)


def test_an_encrypted_retransmission_is_a_retransmission() -> None:
    """Duplicate detection comes before decryption: the repeat of a protected frame is said as a retry,
    not as a second frame not decrypted."""
    enc = [RadioTap() / Dot11(type=2, FCfield="to_DS+protected" + retry, addr1=AP, addr2=STA, addr3=AP, SC=3 << 4)
           / Raw(bytes(range(60))) for retry in ("", "+retry")]
    assert [codes(g) for g in feed_all(enc)] == [["wifi-undecoded"], ["wifi-retry"]]


def test_the_cache_is_bounded() -> None:
    r = Retries(limit=2)
    assert r.duplicate(b"a", 1, False, b"x") is None and r.duplicate(b"b", 1, False, b"x") is None
    assert r.duplicate(b"a", 1, True, b"x") is True  # a is now the most recent
    assert r.duplicate(b"c", 1, False, b"x") is None  # b, the least recent, is forgotten
    assert r.duplicate(b"b", 1, True, b"x") is None and len(r.caches) + len(r.young) == 2 and r.size == 2
    assert r.duplicate(b"a", 1, True, b"y") is None  # a went when b came back


def relay_pair(sta: str, sn: int, seq: int, da: str = STA2) -> list[Packet]:
    """`sta`'s packet for `da` sent to the access point (To DS: Address 3 the destination), and the access
    point's relay of it (From DS: Address 3 the source): one MSDU, twice on the air (IEEE 802.11-2016 5.7,
    the distribution system's service)."""
    body = gcs_heartbeat(mav2(255, 190, seq))
    ip_udp = LLC() / SNAP() / IP(src="192.168.4.2", dst="192.168.4.3") / UDP(sport=14550, dport=14555) / body
    up = RadioTap() / Dot11(type=2, FCfield="to_DS", addr1=AP, addr2=sta, addr3=da, SC=sn << 4) / ip_udp
    down = RadioTap() / Dot11(type=2, FCfield="from_DS", addr1=da, addr2=AP, addr3=sta, SC=(sn + 1) << 4) / ip_udp
    return [up, down]


def test_an_access_points_relay_is_shown_once(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A GCS and a vehicle that are both stations of one access point: every packet is captured twice, and
    was counted as a duplicate (a seq-duplicate finding on every such capture). The relay is said; pymavlink's
    parse of the packets sent to the access point is what is shown, each once."""
    pkts = [p for i in range(5) for p in relay_pair(STA, 2 * i, i)] + relay_pair(STA, 20, 5, da="ff:ff:ff:ff:ff:ff")
    got = feed_all(pkts)
    assert [codes(g) for g in got] == [[], ["wifi-relay"]] * 6
    assert seqs([p for g in got for p in g]) == [0, 1, 2, 3, 4, 5]
    pcap = tmp_path / "relay.pcap"
    wrpcap(str(pcap), pkts)
    (link,) = cli.json("stats", pcap)["links"]
    assert (link["received"], link["duplicates"]) == (6, 0)
    for argv in (("read", pcap, "-T", "jsonl"), ("stats", pcap, "--json")):
        assert cli(*argv, environ={"MAVSCOPE_PURE": "0"}) == cli(*argv, environ={"MAVSCOPE_PURE": "1"})


def test_what_is_no_relay_is_shown() -> None:
    """The access point's own packets (Address 3 itself), another source's, other bytes, a second relay of
    one packet: each is a frame of its own."""
    up, down = relay_pair(STA, 0, 0)
    own = RadioTap() / Dot11(type=2, FCfield="from_DS", addr1=STA2, addr2=AP, addr3=AP, SC=9 << 4) \
        / down.payload.payload
    other_source = relay_pair(STA2, 4, 0, da=STA)[1]
    other_bytes = relay_pair(STA, 6, 1)[1]
    got = feed_all([up, own, other_source, other_bytes, down, down.copy()])
    assert [codes(g) for g in got] == [[], [], [], [], ["wifi-relay"], []]
    assert seqs([p for g in got for p in g]) == [0, 0, 0, 1, 0]


def test_an_encrypted_relay_under_the_group_key() -> None:
    """A station's broadcast sent to the access point under its pairwise key, relayed to every station under
    the group key: the plaintexts are the same MSDU."""
    from mavscope.transport.wpa import Wpa, wifi_key
    from tests.support import wpa as w

    msdu = w.mavlink_packet(255, 3, dst="192.168.4.255")
    up = w.ccmp_frame(w.AP, w.STA, 3, 1, msdu)  # Address 3 the access point: a packet for it, relayed to no one
    down = w.ccmp_frame(w.BROADCAST, w.AP, 4, 1, msdu, key=w.GTK, key_index=1)
    dec = Decapsulator(wpa=Wpa((wifi_key(f"wpa-pwd:{w.PASSPHRASE}:{w.SSID}", 1),)))
    got = feed_all([*w.handshake(), up, down], dec)
    assert codes(got[4]) == [] and codes(got[5]) == []
    dec2 = Decapsulator(wpa=Wpa((wifi_key(f"wpa-pwd:{w.PASSPHRASE}:{w.SSID}", 1),)))
    relayed = w.ccmp_frame(w.BROADCAST, w.AP, 4, 1, msdu, key=w.GTK, key_index=1, a3=w.STA)
    sent = w.ccmp_frame(w.AP, w.STA, 3, 1, msdu, a3=w.BROADCAST)
    got = feed_all([*w.handshake(), sent, relayed], dec2)
    assert codes(got[4]) == [] and codes(got[5]) == ["wifi-relay"]
