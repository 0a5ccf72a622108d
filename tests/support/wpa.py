"""A WPA2-Personal capture made from scratch for the tests: a 4-way handshake, then MAVLink in CCMP frames.

Written from IEEE 802.11-2016 alone and apart from mavscope's decryption (mavscope/transport/wpa.py), so the
two can be checked against each other, and both against tshark, which decrypts the capture with the same
passphrase: PBKDF2 for the PMK (J.4.1), PRF-384 for the PTK (12.7.1.2), the EAPOL-Key frames and their
HMAC-SHA-1 MICs (12.7.2), the GTK in message 3's key data under AES key wrap (RFC 3394), and CCMP's header,
nonce and AAD (12.5.3.3).
"""

from __future__ import annotations

import hashlib
import hmac
import struct

from cryptography.hazmat.primitives.ciphers.aead import AESCCM
from cryptography.hazmat.primitives.keywrap import aes_key_wrap
from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.dot11 import Dot11, Dot11QoS, RadioTap
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import LLC, SNAP
from scapy.packet import Packet, Raw

PASSPHRASE, SSID = "drone-pass-2024", "ArduPilotNet"
AP, STA, STA2 = "02:00:00:00:00:01", "02:00:00:00:00:02", "02:00:00:00:00:03"
BROADCAST = "ff:ff:ff:ff:ff:ff"
ANONCE, SNONCE = bytes(range(32)), bytes(range(100, 132))
GTK = bytes(range(200, 216))
RSN_IE = bytes.fromhex("30140100000fac040100000fac040100000fac020000")  # CCMP, PSK


def mac(text: str) -> bytes:
    return bytes.fromhex(text.replace(":", ""))


def pmk(passphrase: str = PASSPHRASE, ssid: str = SSID) -> bytes:
    return hashlib.pbkdf2_hmac("sha1", passphrase.encode(), ssid.encode(), 4096, 32)


def ptk(key: bytes) -> bytes:
    a, s = mac(AP), mac(STA)
    data = min(a, s) + max(a, s) + min(ANONCE, SNONCE) + max(ANONCE, SNONCE)
    out = b"".join(hmac.new(key, b"Pairwise key expansion\x00" + data + bytes((i,)), hashlib.sha1).digest()
                   for i in range(3))
    return out[:48]


KCK, KEK, TK = (lambda p: (p[:16], p[16:32], p[32:48]))(ptk(pmk()))


def eapol_key(info: int, replay: int, nonce: bytes, key_data: bytes = b"", kck: bytes | None = None) -> bytes:
    """An RSN EAPOL-Key frame, its MIC computed over itself with the MIC field zeroed when `kck` is given."""
    body = (struct.pack("!BHHQ", 2, info, 16, replay) + nonce + bytes(16 + 8 + 8 + 16)
            + struct.pack("!H", len(key_data)) + key_data)
    frame = struct.pack("!BBH", 2, 3, len(body)) + body
    if kck is not None:
        frame = frame[:81] + hmac.new(kck, frame, hashlib.sha1).digest()[:16] + frame[97:]
    return frame


def message3_key_data() -> bytes:
    kd = RSN_IE + bytes((0xDD, 22)) + bytes.fromhex("000fac01") + bytes((1, 0)) + GTK  # GTK KDE, key index 1
    kd += b"\xdd" + bytes(-(len(kd) + 1) % 8)
    return aes_key_wrap(KEK, kd)


def eapol_frame(a1: str, a2: str, eapol: bytes, sn: int) -> Packet:
    fc = "to_DS" if a1 == AP else "from_DS"
    return RadioTap() / Dot11(type=2, subtype=0, FCfield=fc, addr1=a1, addr2=a2, addr3=AP, SC=sn << 4) / LLC() / \
        SNAP(code=0x888E) / Raw(eapol)


def handshake() -> list[Packet]:
    return [
        eapol_frame(STA, AP, eapol_key(0x008A, 1, ANONCE), 1),  # message 1: pairwise, ACK
        eapol_frame(AP, STA, eapol_key(0x010A, 1, SNONCE, RSN_IE, KCK), 1),  # 2: MIC
        eapol_frame(STA, AP, eapol_key(0x13CA, 2, ANONCE, message3_key_data(), KCK), 2),  # 3: install, encrypted
        eapol_frame(AP, STA, eapol_key(0x030A, 2, bytes(32), b"", KCK), 2),  # 4: MIC, secure
    ]


def mavlink_packet(sysid: int, seq: int, arm: bool = False, dst: str = "192.168.4.1") -> bytes:
    """LLC/SNAP, IP and UDP around a HEARTBEAT (and an ARM COMMAND_LONG) of `sysid`."""
    m = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=190 if sysid == 255 else 1)
    m.seq = seq
    body = m.heartbeat_encode(6 if sysid == 255 else 2, 3, 0, 0, 4).pack(m)
    if arm:
        body += m.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(m)
    src = "192.168.4.2" if sysid == 255 else "192.168.4.1"
    if sysid != 255:
        dst = "192.168.4.2" if dst == "192.168.4.1" else dst
    return bytes(LLC() / SNAP(code=0x0800) / IP(src=src, dst=dst) / UDP(sport=14550, dport=14555) / body)


def ccmp_frame(a1: str, a2: str, sn: int, pn: int, plain: bytes, key: bytes = TK, key_index: int = 0,
               tid: int = 0, retry: bool = False) -> Packet:
    """A protected QoS data frame: its CCMP header, `plain` encrypted and its 8-byte MIC (12.5.3.3)."""
    fc = ("to_DS" if a1 == AP else "from_DS") + "+protected" + ("+retry" if retry else "")
    hdr = bytes(Dot11(type=2, subtype=8, FCfield=fc, addr1=a1, addr2=a2, addr3=AP, SC=sn << 4) / Dot11QoS(TID=tid))
    p = pn.to_bytes(6, "little")
    ccmp = bytes((p[0], p[1], 0, 0x20 | key_index << 6)) + p[2:6]
    aad = bytes((hdr[0] & 0x8F, (hdr[1] & 0xC7 | 0x40) & 0x7F)) + hdr[4:22] + bytes((hdr[22] & 0x0F, 0)) + \
        bytes((hdr[24] & 0x0F, 0))
    nonce = bytes((tid,)) + mac(a2) + pn.to_bytes(6, "big")
    sealed = AESCCM(key, tag_length=8).encrypt(nonce, plain, aad)
    return RadioTap() / Raw(hdr + ccmp + sealed)
