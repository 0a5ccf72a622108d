"""WPA2-Personal decryption (mavscope.transport.wpa, `--wifi-key`): MAVLink inside a protected Wi-Fi network.

The capture is built by tests/support/wpa.py from IEEE 802.11-2016 alone (a 4-way handshake, CCMP frames).
The expected frames are tshark's: it decrypts the capture with the same passphrase, and pymavlink parses the
UDP payloads it finds. Where the standard's receiver and tshark part (tshark checks no packet numbers, so it
shows a replayed frame), the standard's rule is written out by hand in the test. The PSK mapping is checked
against the test vectors of 802.11-2016 J.4.2.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.keywrap import aes_key_wrap
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink
from scapy.packet import Packet, Raw
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_IEEE802_11_RADIOTAP, Record
from mavscope.errors import UsageError
from mavscope.transport.decap import Decapsulator
from mavscope.transport.wpa import WifiKey, Wpa, wifi_key
from tests.support import wpa as w

KEY = f"wpa-pwd:{w.PASSPHRASE}:{w.SSID}"
SECRETS = (w.PASSPHRASE, w.pmk().hex(), w.TK.hex(), w.GTK.hex(), w.KCK.hex(), w.KEK.hex())


def scenario() -> tuple[list[Packet], dict[int, str]]:
    """The capture's frames, and the note on each record that the receiver does not read."""
    arm = w.mavlink_packet(255, 0, arm=True)
    pkts = w.handshake() + [
        w.ccmp_frame(w.AP, w.STA, 3, 1, arm),  # 5: the GCS's HEARTBEAT and ARM
        w.ccmp_frame(w.STA, w.AP, 3, 1, w.mavlink_packet(1, 0)),  # 6: the vehicle's, on the AP's own counter
        w.ccmp_frame(w.BROADCAST, w.AP, 4, 1, w.mavlink_packet(1, 1, dst="192.168.4.255"), key=w.GTK,
                     key_index=1),  # 7: group-addressed, under the GTK
        w.ccmp_frame(w.AP, w.STA, 9, 1, arm),  # 8: record 5 again (another 802.11 number): a replay
        w.ccmp_frame(w.AP, w.STA, 9, 1, arm, retry=True),  # 9: its retransmission
        w.ccmp_frame(w.AP, w.STA, 10, 2, w.mavlink_packet(255, 1)),  # 10: a new packet number
        w.ccmp_frame(w.AP, w.STA2, 1, 1, w.mavlink_packet(255, 2)),  # 11: a station whose handshake is missing
        w.ccmp_frame(w.AP, w.STA, 11, 3, w.mavlink_packet(255, 3), key=bytes(16)),  # 12: forged (another key)
        w.ccmp_frame(w.AP, w.STA, 12, 4, w.mavlink_packet(255, 4), tid=5),  # 13: another TID
    ]
    notes = {8: "wifi-replay", 9: "wifi-retry", 11: "wifi-undecoded", 12: "wifi-decrypt-failed"}
    return pkts, notes


def frames_of(payload: bytes) -> list[tuple[int, int, int, int]]:
    return [(f.get_srcSystem(), f.get_srcComponent(), f.get_msgId(), f.get_seq())
            for f in mavlink.MAVLink(None).parse_buffer(payload) or ()]


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("wpa") / "wpa2.pcap"
    wrpcap(str(path), scenario()[0])
    return path


def test_the_psk_mapping_test_vectors() -> None:
    """IEEE 802.11-2016 J.4.2."""
    assert wifi_key("wpa-pwd:password:IEEE", 1).pmk.hex() == \
        "f42c6fc52df0ebef9ebb4b90b38a5f902e83fe1b135a70e23aed762e9710a12e"
    assert wifi_key("wpa-pwd:ThisIsAPassword:ThisIsASSID", 1).pmk.hex() == \
        "0dc0d6eb90555ed6419756b9a15ec3e3209b63df707dd508d14581f8982721af"
    assert wifi_key("wpa-psk:" + "ab" * 32, 1).pmk == bytes([0xAB]) * 32
    assert wifi_key("wpa-pwd:pass:word:with%3acolon", 1).pmk == w.pmk("pass:word", "with:colon")


@pytest.mark.parametrize("spec", ["wpa-pwd:short:SSID", "wpa-pwd:no-ssid-given", "wpa-psk:abcd", "wep:12345",
                                  "wpa-pwd:secret-passphrase:bad%zz", "wpa-pwd:" + "x" * 64 + ":S"])
def test_a_wrong_spec_is_a_usage_error_without_the_secret(spec: str) -> None:
    with pytest.raises(UsageError) as e:
        wifi_key(spec, 1)
    assert "--wifi-key #1" in str(e.value)
    assert not any(part in str(e.value) for part in ("short", "secret-passphrase", "abcd", "12345", "x" * 8))


def test_tshark_decrypts_the_same_frames(capture: Path, tshark_exe: str, cli) -> None:  # type: ignore[no-untyped-def]
    out = subprocess.run([tshark_exe, "-o", "wlan.enable_decryption:TRUE", "-o",
                          f'uat:80211_keys:"wpa-pwd","{w.PASSPHRASE}:{w.SSID}"', "-r", str(capture), "-T", "fields",
                          "-e", "frame.number", "-e", "udp.payload"], capture_output=True, text=True, check=True).stdout
    theirs = {int(n): frames_of(bytes.fromhex(p)) for n, p in (line.split("\t") for line in out.splitlines()) if p}
    _, notes = scenario()
    assert set(theirs) == {5, 6, 7, 8, 9, 10, 13}  # tshark reads neither the unknown station nor the forged frame
    expected = [(n, *f) for n, fs in sorted(theirs.items()) if n not in notes for f in fs]  # the receiver's rule
    got = cli.jsonl(capture, "--wifi-key", KEY)
    assert [(f["frame"], f["sysid"], f["compid"], f["msgid"], f["seq"]) for f in got] == expected
    assert [(f["src"], f["dst"]) for f in got[:4]] == [
        ("192.168.4.2:14550", "192.168.4.1:14555"), ("192.168.4.2:14550", "192.168.4.1:14555"),
        ("192.168.4.1:14550", "192.168.4.2:14555"), ("192.168.4.1:14550", "192.168.4.255:14555")]


def test_each_frame_not_read_is_one_note(capture: Path, cli) -> None:  # type: ignore[no-untyped-def]
    pkts, notes = scenario()
    got = feed(pkts, (wifi_key(KEY, 1),))
    assert {i: c for i, g in enumerate(got, 1) for c in codes(g)} == notes
    lines = cli("read", capture, "--wifi-key", KEY, "-q").err.splitlines()
    assert [int(line.split("record ")[1].split(":")[0]) for line in lines] == sorted(notes)
    assert "not above the 1 its key accepted" in next(line for line in lines if "record 8:" in line)
    audit = cli("audit", capture, "--wifi-key", KEY, "--json")
    found = {f["code"]: f["frames"] for f in json.loads(audit.out)["findings"]}
    assert found == {"wifi-replay": [8], "wifi-decrypt-failed": [12]}


def test_without_the_passphrase_nothing_is_decrypted(capture: Path, cli) -> None:  # type: ignore[no-untyped-def]
    wrong = (f"wpa-pwd:another-passphrase:{w.SSID}", f"wpa-pwd:{w.PASSPHRASE}:X")
    for argv in ((), ("--wifi-key", wrong[0]), ("--wifi-key", wrong[1])):
        _, out, err = cli("read", capture, "-T", "jsonl", *argv)
        assert out == "" and err.count("802.11") == 9  # each protected frame (record 9: its retransmission)


def test_secrets_never_show(capture: Path, cli) -> None:  # type: ignore[no-untyped-def]
    for argv in (("read", capture), ("read", capture, "-V"), ("read", capture, "-T", "json"), ("stats", capture),
                 ("stats", capture, "--json"), ("audit", capture, "--json"), ("verify", capture)):
        r = cli(*argv, "--wifi-key", KEY)
        assert not any(s in r.out or s in r.err for s in SECRETS), argv
    assert not any(s in repr(wifi_key(KEY, 1)) + repr(Wpa((wifi_key(KEY, 1),))) for s in SECRETS)


def test_both_engines_agree(capture: Path, cli) -> None:  # type: ignore[no-untyped-def]
    for argv in (("read", capture, "-T", "jsonl"), ("stats", capture, "--json"), ("audit", capture, "--json")):
        pure = cli(*argv, "--wifi-key", KEY, environ={"MAVSCOPE_PURE": "1"})
        assert cli(*argv, "--wifi-key", KEY, environ={"MAVSCOPE_PURE": "0"}) == pure


def feed(pkts: list[Packet], keys: tuple[WifiKey, ...]) -> list[list]:
    dec = Decapsulator(wpa=Wpa(keys))
    return [dec.feed(Record(i, float(i), LINKTYPE_IEEE802_11_RADIOTAP, bytes(p), 0, len(bytes(p))))
            for i, p in enumerate(pkts, 1)]


def codes(got: list) -> list[str]:
    return [n.code for p in got for n in p.notes]


def test_a_key_installed_again_keeps_its_packet_numbers() -> None:
    """Message 3 sent again (its ACK lost) reinstalls the same key: a receiver that reset its packet
    numbers then would accept a replay (KRACK, 2017). The replay after it is still one."""
    hs = w.handshake()
    arm = w.mavlink_packet(255, 0, arm=True)
    got = feed(hs + [w.ccmp_frame(w.AP, w.STA, 3, 7, arm), hs[2], hs[3], w.ccmp_frame(w.AP, w.STA, 4, 7, arm)],
               (wifi_key(KEY, 1),))
    assert [codes(g) for g in got[4:]] == [[], [], [], ["wifi-replay"]]


def test_a_forged_handshake_installs_nothing() -> None:
    """Message 2 with a MIC made without the passphrase (an attacker's) does not give its nonce's keys."""
    hs = w.handshake()
    forged = w.eapol_frame(w.AP, w.STA, w.eapol_key(0x010A, 1, bytes(32), w.RSN_IE, bytes(16)), 1)
    got = feed([hs[0], forged, w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0))], (wifi_key(KEY, 1),))
    assert codes(got[2]) == ["wifi-undecoded"] and "no key for it" in got[2][0].notes[0].message


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.binary(max_size=160), st.integers(0, 0xFFFF))
def test_any_eapol_or_protected_body_never_raises(raw: bytes, info: int) -> None:
    hs = w.handshake()
    eapol = w.eapol_key(info, 1, w.SNONCE, raw[:40]) + raw
    pkts = [hs[0], hs[1], hs[2], w.eapol_frame(w.AP, w.STA, eapol[:len(raw)], 3),
            w.eapol_frame(w.STA, w.AP, eapol, 3), w.ccmp_frame(w.AP, w.STA, 3, 1, raw)]
    pkts.append(Raw(bytes(pkts[-1])[:20 + len(raw) % 40]))  # a protected frame cut anywhere
    feed(pkts, (wifi_key(KEY, 1),))


def test_a_group_key_handshake_under_the_pair_key_gives_the_new_gtk() -> None:
    """The access point's group key message 1 (12.7.7.2) travels encrypted under the pair's TK, its key data
    wrapped under the KEK: the new GTK (index 2) decrypts the group-addressed frames after it."""
    new_gtk = bytes(range(50, 66))
    kd = bytes((0xDD, 22)) + bytes.fromhex("000fac01") + bytes((2, 0)) + new_gtk
    kd += b"\xdd" + bytes(-(len(kd) + 1) % 8)
    message = w.eapol_key(0x1382, 3, bytes(32), aes_key_wrap(w.KEK, kd), w.KCK)  # ACK, MIC, secure, encrypted
    snap = bytes.fromhex("aaaa03000000888e") + message
    after = w.ccmp_frame(w.BROADCAST, w.AP, 8, 1, w.mavlink_packet(1, 5, dst="192.168.4.255"), key=new_gtk,
                         key_index=2)
    got = feed(w.handshake() + [w.ccmp_frame(w.STA, w.AP, 7, 1, snap), after], (wifi_key(KEY, 1),))
    assert codes(got[4]) == [] and [frames_of(p.data) for p in got[5]] == [[(1, 1, 0, 5)]]
    unrekeyed = feed(w.handshake() + [after], (wifi_key(KEY, 1),))
    assert codes(unrekeyed[4]) == ["wifi-undecoded"]


def test_a_flood_of_first_messages_forgets_no_key() -> None:
    """Anyone can send message 1; a flood of them from made-up stations fills the table of pending
    handshakes, not the one of the pairs whose keys verified."""
    wpa = Wpa((wifi_key(KEY, 1),), limit=4)
    dec = Decapsulator(wpa=wpa)
    flood = [w.eapol_frame(f"02:00:00:00:01:{i:02x}", w.AP, w.eapol_key(0x008A, 1, w.ANONCE), i) for i in range(9)]
    pkts = [*w.handshake(), *flood, w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0))]
    got = [dec.feed(Record(i, float(i), LINKTYPE_IEEE802_11_RADIOTAP, bytes(p), 0, len(bytes(p))))
           for i, p in enumerate(pkts, 1)]
    assert not codes(got[-1]) and frames_of(got[-1][0].data) == [(255, 190, 0, 0)]
    assert len(wpa.pending) == 4 and len(wpa.pairs) == 1


def test_a_written_subset_can_be_decrypted_again(capture: Path, cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                 tshark_exe: str) -> None:
    """`read -w` writes with each decrypted frame the handshake messages its key came from (messages 1 and
    2; 3 too for the group key): the ARM, filtered and written, is read from the written capture with the
    passphrase, as tshark reads it there."""
    out = tmp_path / "arm.pcap"
    assert cli("read", capture, "--wifi-key", KEY, "-Y", "COMMAND_LONG", "-w", out).status == 0
    again = cli.jsonl(out, "--wifi-key", KEY)
    assert [(f["frame"], f["msgid"]) for f in again] == [(3, 0), (3, 76)]  # records 1, 2 (the handshake), 5
    theirs = subprocess.run([tshark_exe, "-o", "wlan.enable_decryption:TRUE", "-o",
                             f'uat:80211_keys:"wpa-pwd","{w.PASSPHRASE}:{w.SSID}"', "-r", str(out), "-T", "fields",
                             "-e", "udp.payload"], capture_output=True, text=True, check=True).stdout.split("\n")
    assert [bool(line) for line in theirs[:3]] == [False, False, True]
    group = tmp_path / "group.pcap"
    assert cli("read", capture, "--wifi-key", KEY, "-Y", "ip.dst == 192.168.4.255", "-w", group).status == 0
    assert [(f["frame"], f["sysid"]) for f in cli.jsonl(group, "--wifi-key", KEY)] == [(4, 1)]  # 1, 2, 3 and 7
