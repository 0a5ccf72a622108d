"""WPA2 decryption (mavscope.transport.wpa, .ccmp) on what a review of it found: real networks' rekeys and
block acks, GCMP, and an attacker's frames (injected plaintext, replayed handshakes, a forged message 1).

Each expected answer comes from tshark decrypting the same capture where it can, and else from what the
receiving station's code does, cited in the test: wpa_supplicant (rsn_supp/wpa.c), hostapd (ap/wpa_auth.c)
and Linux's mac80211 (net/mac80211/rx.c).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink
from scapy.packet import Packet
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_IEEE802_11_RADIOTAP, Record
from mavscope.transport.decap import Decapsulator
from mavscope.transport.wpa import Wpa, wifi_key
from tests.support import wpa as w

KEY = f"wpa-pwd:{w.PASSPHRASE}:{w.SSID}"
SNAP_EAPOL = bytes.fromhex("aaaa03000000888e")


def n32(b: int) -> bytes:
    return bytes([b]) * 32


def feed(pkts: list[Packet | bytes], snapped: int = 0) -> list[list]:
    dec = Decapsulator(wpa=Wpa((wifi_key(KEY, 1),)))
    out = []
    for i, p in enumerate(pkts, 1):
        raw = p if isinstance(p, bytes) else bytes(p)
        out.append(dec.feed(Record(i, float(i), LINKTYPE_IEEE802_11_RADIOTAP, raw, 0, len(raw) + snapped)))
    return out


def codes(got: list) -> list[list[str]]:
    return [[n.code for p in g for n in p.notes] for g in got]


def seqs(got: list) -> list[int]:
    return [f.get_seq() for g in got for p in g for f in mavlink.MAVLink(None).parse_buffer(p.data) or ()]


def tshark_records(tshark: str, path: Path) -> list[int]:
    out = subprocess.run([tshark, "-o", "wlan.enable_decryption:TRUE", "-o",
                          f'uat:80211_keys:"wpa-pwd","{w.PASSPHRASE}:{w.SSID}"', "-r", str(path), "-T", "fields",
                          "-e", "frame.number", "-e", "udp.payload"], capture_output=True, text=True, check=True).stdout
    return [int(n) for n, p in (line.split("\t") for line in out.splitlines()) if p]


def rekey(secure_m2: bool) -> list[Packet]:
    """A first handshake, a frame, then a rekey whose messages travel under the first TK, then a frame under
    the second TK. wpa_supplicant sets Secure in message 2 once it has a PTK (wpa_supplicant_send_2_of_4:
    `if (sm->ptk_set && sm->proto != WPA_PROTO_WPA) key_info |= WPA_KEY_INFO_SECURE`); hostapd tells
    message 2 from 4 by its key data (wpa_receive)."""
    _, _, tk1 = w.keys_for(n32(1), n32(2))
    kck2, kek2, tk2 = w.keys_for(n32(3), n32(4))
    info2 = 0x030A if secure_m2 else 0x010A
    msgs = [(w.STA, w.AP, w.eapol_key(0x008A, 3, n32(3))), (w.AP, w.STA, w.eapol_key(info2, 3, n32(4), w.RSN_IE, kck2)),
            (w.STA, w.AP, w.eapol_key(0x13CA, 4, n32(3), w.gtk_key_data(kek2), kck2)),
            (w.AP, w.STA, w.eapol_key(0x030A, 4, bytes(32), b"", kck2))]
    pns = {w.STA: 2, w.AP: 2}
    under_tk1 = []
    for i, (a1, a2, m) in enumerate(msgs):
        under_tk1.append(w.ccmp_frame(a1, a2, 4 + i, pns[a2], SNAP_EAPOL + m, key=tk1, tid=7))
        pns[a2] += 1
    return [*w.handshake(n32(1), n32(2)), w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0), key=tk1),
            *under_tk1, w.ccmp_frame(w.AP, w.STA, 9, 1, w.mavlink_packet(255, 1), key=tk2)]


def test_a_rekey_whose_message_2_is_secure(tmp_path: Path, tshark_exe: str) -> None:
    for secure in (False, True):
        pkts = rekey(secure)
        path = tmp_path / f"rekey{secure}.pcap"
        wrpcap(str(path), pkts)
        assert tshark_records(tshark_exe, path) == [5, 10]
        got = feed(pkts)
        assert seqs(got) == [0, 1] and not any(codes(got))


def test_a_protected_frame_longer_than_any_mpdu() -> None:
    big = bytes(w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0))) + bytes(70000)  # (no cipher seals so much)
    got = feed([*w.handshake(), big])
    assert codes(got)[4] == ["malformed-packet"] and "longer than any frame a radio sends" in got[4][0].notes[0].message


def test_plaintext_between_stations_with_keys_is_dropped(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """mac80211 drops a data frame that is not protected once the station has a key (ieee80211_drop_unencrypted;
    EAPOL alone passes, through the control port): an injected ARM in clear is never read."""
    from scapy.layers.dot11 import Dot11, Dot11QoS, RadioTap

    clear = RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS", addr1=w.AP, addr2=w.STA, addr3=w.AP, SC=9 << 4) \
        / Dot11QoS() / w.mavlink_packet(255, 5, arm=True)
    before = RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS", addr1=w.AP, addr2=w.STA, addr3=w.AP, SC=0) \
        / Dot11QoS() / w.mavlink_packet(255, 4)
    pkts = [before, *w.handshake(), w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0)), clear]
    got = feed(pkts)
    assert seqs(got) == [4, 0] and codes(got)[6] == ["wifi-unprotected"]  # (before the handshake: no keys yet)
    path = tmp_path / "clear.pcap"
    wrpcap(str(path), pkts)
    audit = json.loads(cli("audit", path, "--wifi-key", KEY, "--json").out)
    found = {f["code"]: f["frames"] for f in audit["findings"]}
    assert found == {"wifi-unprotected": [7]}


def test_a_replayed_handshake_installs_no_old_key() -> None:
    """Message 1 and 2 of an old handshake sent again: the station drops a message 1 whose replay counter is
    not above the last it verified (wpa_supplicant: "EAPOL-Key Replay Counter did not increase"), so the
    old key is not installed again, and a frame recorded under it is not read."""
    first = w.handshake(n32(1), n32(2), replay=1)
    _, _, tk1 = w.keys_for(n32(1), n32(2))
    second = w.handshake(n32(3), n32(4), replay=3)
    third = w.handshake(n32(5), n32(6), replay=5)
    arm = w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0, arm=True), key=tk1)
    got = feed([*first, arm, *second, *third, first[0], first[1], arm])
    assert seqs(got[4:5]) and not seqs(got[-1:]) and codes(got)[-1] == ["wifi-decrypt-failed"]


def test_a_forged_message_1_between_1_and_2_changes_nothing() -> None:
    """Anyone can send message 1: one with another ANonce between the access point's message 1 and the
    station's message 2 does not make the station's keys unreachable (hostapd pairs message 2 with the
    message 1 of its replay counter; the few kept are each tried)."""
    hs = w.handshake()
    forged = w.eapol_frame(w.STA, w.AP, w.eapol_key(0x008A, 1, n32(9)), 1)
    got = feed([hs[0], forged, *hs[1:], w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0))])
    assert seqs(got) == [0] and not any(codes(got))


def test_block_ack_reordering_and_a_replay_into_its_window() -> None:
    """Under block ack the receiver reorders frames by sequence number before it checks packet numbers
    (mac80211: ieee80211_rx_reorder_ampdu, then the key's check): frame 11's only copy the monitor saw
    comes after 12 and is read; a recorded frame sent again with its sequence number rewritten into the
    window (the AAD does not cover it) has a packet number below its new neighbours' and is a replay."""
    def f(sn: int, pn: int, seq: int, retry: bool = False) -> Packet:
        return w.ccmp_frame(w.STA, w.AP, sn, pn, w.mavlink_packet(1, seq), tid=0, retry=retry)

    got = feed([*w.handshake(), f(10, 1, 10), f(12, 3, 12), f(11, 2, 11, retry=True), f(20, 4, 20), f(15, 2, 11)])
    assert seqs(got) == [10, 12, 11, 20] and codes(got)[4:] == [[], [], [], [], ["wifi-replay"]]
    far = feed([*w.handshake(), f(10, 1, 1), f(400, 2, 2), f(10, 1, 1, retry=True)])  # 390 behind: past any window
    assert codes(far)[4:] == [[], [], ["wifi-replay"]]


def test_a_retransmission_far_behind_in_an_he_window() -> None:
    """802.11ax's block ack window is 256 frames: a retransmission 89 behind the newest is still one."""
    pkts = [w.ccmp_frame(w.STA, w.AP, 10, 1, w.mavlink_packet(1, 0)), w.ccmp_frame(w.STA, w.AP, 99, 2,
            w.mavlink_packet(1, 1)), w.ccmp_frame(w.STA, w.AP, 10, 1, w.mavlink_packet(1, 0), retry=True)]
    assert codes(feed([*w.handshake(), *pkts]))[4:] == [[], [], ["wifi-retry"]]


def test_a_snapped_protected_frame_is_not_decrypted() -> None:
    cut = bytes(w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0)))[:-12]
    got = feed([*w.handshake(), cut], snapped=12)
    assert codes(got)[4] == ["wifi-undecoded"] and "snap length" in got[4][0].notes[0].message


def test_gcmp_is_decrypted_and_tkip_is_said(tmp_path: Path, tshark_exe: str) -> None:
    """A network whose station chose GCMP-128 (its RSNE in message 2: 00-0F-AC:8) is decrypted as tshark
    decrypts it; one whose group cipher is TKIP (a WPA/WPA2 mixed network: 00-0F-AC:2) has its broadcasts
    said to be under TKIP, not taken for forged frames."""
    gcmp_rsn = bytes.fromhex("30140100000fac080100000fac080100000fac020000")
    pkts = [*w.handshake(rsn=gcmp_rsn), w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0), gcmp=True)]
    path = tmp_path / "gcmp.pcap"
    wrpcap(str(path), pkts)
    assert tshark_records(tshark_exe, path) == [5]
    got = feed(pkts)
    assert seqs(got) == [0] and not any(codes(got))
    mixed_rsn = bytes.fromhex("30140100000fac020100000fac040100000fac020000")
    bcast = w.ccmp_frame(w.BROADCAST, w.AP, 4, 1, w.mavlink_packet(1, 1, dst="192.168.4.255"), key=w.GTK, key_index=1)
    got = feed([*w.handshake(rsn=mixed_rsn), w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0)), bcast])
    assert seqs(got) == [0] and codes(got)[5] == ["wifi-undecoded"] and "TKIP" in got[5][0].notes[0].message


def test_radiotap_padding_is_not_the_frames_body() -> None:
    """A retransmission whose radiotap alignment bytes differ is the same frame: a duplicate, no conflict."""
    a = w.ccmp_frame(w.AP, w.STA, 5, 1, w.mavlink_packet(255, 0), pad=b"\x00\x00")
    b = w.ccmp_frame(w.AP, w.STA, 5, 1, w.mavlink_packet(255, 0), retry=True, pad=b"\xff\xff")
    got = feed([*w.handshake(), a, b])
    assert seqs(got) == [0] and codes(got)[4:] == [[], ["wifi-retry"]]


def mgmt(subtype: int, a1: str, a2: str, sn: int) -> Packet:
    from scapy.layers.dot11 import Dot11, RadioTap

    return RadioTap() / Dot11(type=0, subtype=subtype, addr1=a1, addr2=a2, addr3=w.AP, SC=sn << 4)


def test_a_station_that_associates_again(tmp_path: Path, tshark_exe: str) -> None:
    """A station that leaves and associates again starts a new handshake whose replay counters start at 1
    again (hostapd's state is new; wpa_supplicant clears its counter on every association:
    wpa_sm_notify_assoc): it is decrypted, as tshark decrypts it. A handshake recorded before and sent again
    after the new association installs nothing: its key was installed once already."""
    first, second = w.handshake(n32(1), n32(2)), w.handshake(n32(3), n32(4))
    _, _, tk1 = w.keys_for(n32(1), n32(2))
    _, _, tk2 = w.keys_for(n32(3), n32(4))
    pkts = [*first, w.ccmp_frame(w.AP, w.STA, 5, 1, w.mavlink_packet(255, 0), key=tk1),
            mgmt(12, w.AP, w.STA, 6), mgmt(11, w.AP, w.STA, 7), mgmt(0, w.AP, w.STA, 8),  # deauth, auth, assoc
            *second, w.ccmp_frame(w.AP, w.STA, 9, 1, w.mavlink_packet(255, 1), key=tk2)]
    path = tmp_path / "again.pcap"
    wrpcap(str(path), pkts)
    assert tshark_records(tshark_exe, path) == [5, 13]
    got = feed(pkts)
    assert seqs(got) == [0, 1] and not any(codes(got))
    replayed = feed([*pkts, mgmt(12, w.AP, w.STA, 10), first[0], first[1],
                     w.ccmp_frame(w.AP, w.STA, 11, 7, w.mavlink_packet(255, 2, arm=True), key=tk1)])
    assert codes(replayed)[-1] == ["wifi-decrypt-failed"]  # tk1's frames, after tk2: the old key is not back


def test_plaintext_after_the_station_left_is_read() -> None:
    """Once the station is deauthenticated its keys are gone (mac80211 frees them with the station), and a
    receiver drops no plaintext for lack of them: an access point that now runs open is read."""
    from scapy.layers.dot11 import Dot11, Dot11QoS, RadioTap

    clear = RadioTap() / Dot11(type=2, subtype=8, FCfield="to_DS", addr1=w.AP, addr2=w.STA, addr3=w.AP, SC=9 << 4) \
        / Dot11QoS() / w.mavlink_packet(255, 5)
    got = feed([*w.handshake(), w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0)), mgmt(12, w.STA, w.AP, 4),
                clear])
    assert seqs(got) == [0, 5] and not any(codes(got))
    broadcast = feed([*w.handshake(), mgmt(12, w.BROADCAST, w.AP, 4), clear])  # every station sent away
    assert seqs(broadcast) == [5] and not any(codes(broadcast))


def test_a_gap_of_thousands_of_sequence_numbers() -> None:
    """A monitor out of range for a while misses thousands of frames: what comes after carries higher
    packet numbers and is read (mac80211 without block ack compares packet numbers only)."""
    pkts = [w.ccmp_frame(w.AP, w.STA, sn, pn, w.mavlink_packet(255, pn))
            for pn, sn in enumerate([*range(3, 13), *range(2303, 2313)], 1)]
    got = feed([*w.handshake(), *pkts])
    assert seqs(got) == list(range(1, 21)) and not any(codes(got))


def test_a_sparse_capture_of_a_block_ack_stream() -> None:
    """The monitor caught one frame in six of a block ack stream (sequence numbers wrapping), then a late
    retransmission of one it missed: between its neighbours, it is read."""
    from mavscope.transport.ccmp import PacketNumbers

    numbers = PacketNumbers(0, 1)
    assert all(numbers.accept(sn % 4096, sn + 1) is None for sn in range(6, 2700, 6))
    assert numbers.accept(2692 % 4096, 2693) is None and numbers.accept(2690, 2689) is not None


def test_message_2_answering_a_message_1_the_monitor_missed() -> None:
    """hostapd sends message 1 again with a higher counter before message 2 comes; the station answers the
    first (which the monitor missed): hostapd accepts any counter it sent lately, and the ANonce is the same."""
    hs = w.handshake()
    m1_again = w.eapol_frame(w.STA, w.AP, w.eapol_key(0x008A, 2, w.ANONCE), 1)
    got = feed([m1_again, *hs[1:], w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0))])
    assert seqs(got) == [0] and not any(codes(got))
