"""A WPA2-Personal capture made from scratch for the tests: a 4-way handshake, then MAVLink in CCMP frames.

Written from IEEE 802.11-2016 alone and apart from mavscope's decryption (mavscope/transport/wpa.py), so the
two can be checked against each other, and both against tshark, which decrypts the capture with the same
passphrase: PBKDF2 for the PMK (J.4.1), PRF-384 for the PTK (12.7.1.2), the EAPOL-Key frames and their
HMAC-SHA-1 MICs (12.7.2), the GTK in message 3's key data under AES key wrap (RFC 3394), and CCMP's header,
nonce and AAD (12.5.3.3) and GCMP's nonce (12.5.5.3).
"""

from __future__ import annotations

import hashlib
import hmac
import struct

from cryptography.hazmat.primitives.ciphers.aead import AESCCM, AESGCM
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


def ptk(key: bytes, anonce: bytes = ANONCE, snonce: bytes = SNONCE, sta: str = STA) -> bytes:
    a, s = mac(AP), mac(sta)
    data = min(a, s) + max(a, s) + min(anonce, snonce) + max(anonce, snonce)
    out = b"".join(hmac.new(key, b"Pairwise key expansion\x00" + data + bytes((i,)), hashlib.sha1).digest()
                   for i in range(3))
    return out[:48]


def keys_for(anonce: bytes = ANONCE, snonce: bytes = SNONCE, sta: str = STA) -> tuple[bytes, bytes, bytes]:
    """The KCK, KEK and TK of a handshake of `sta` with these nonces."""
    p = ptk(pmk(), anonce, snonce, sta)
    return p[:16], p[16:32], p[32:48]


KCK, KEK, TK = keys_for()


def eapol_key(info: int, replay: int, nonce: bytes, key_data: bytes = b"", kck: bytes | None = None) -> bytes:
    """An RSN EAPOL-Key frame, its MIC computed over itself with the MIC field zeroed when `kck` is given."""
    body = (struct.pack("!BHHQ", 2, info, 16, replay) + nonce + bytes(16 + 8 + 8 + 16)
            + struct.pack("!H", len(key_data)) + key_data)
    frame = struct.pack("!BBH", 2, 3, len(body)) + body
    if kck is not None:
        frame = frame[:81] + hmac.new(kck, frame, hashlib.sha1).digest()[:16] + frame[97:]
    return frame


def gtk_key_data(kek: bytes = KEK, gtk: bytes = GTK, index: int = 1, rsn: bytes = RSN_IE) -> bytes:
    """Message 3's key data: the RSNE and the GTK KDE, padded and wrapped under the KEK."""
    kd = rsn + bytes((0xDD, 6 + len(gtk))) + bytes.fromhex("000fac01") + bytes((index, 0)) + gtk
    kd += b"\xdd" + bytes(-(len(kd) + 1) % 8)
    return aes_key_wrap(kek, kd)


def eapol_frame(a1: str, a2: str, eapol: bytes, sn: int) -> Packet:
    fc = "to_DS" if a1 == AP else "from_DS"
    return RadioTap() / Dot11(type=2, subtype=0, FCfield=fc, addr1=a1, addr2=a2, addr3=AP, SC=sn << 4) / LLC() / \
        SNAP(code=0x888E) / Raw(eapol)


def handshake(anonce: bytes = ANONCE, snonce: bytes = SNONCE, replay: int = 1, rsn: bytes = RSN_IE,
              gtk: bytes = GTK, sta: str = STA, secure_m2: bool = False) -> list[Packet]:
    """A 4-way handshake of `sta` with the access point (message 2 with Secure set, as wpa_supplicant sends
    it on a rekey, when `secure_m2`)."""
    kck, kek, _ = keys_for(anonce, snonce, sta)
    return [
        eapol_frame(sta, AP, eapol_key(0x008A, replay, anonce), 1),  # message 1: pairwise, ACK
        eapol_frame(AP, sta, eapol_key(0x030A if secure_m2 else 0x010A, replay, snonce, rsn, kck), 1),  # 2: MIC
        eapol_frame(sta, AP, eapol_key(0x13CA, replay + 1, anonce, gtk_key_data(kek, gtk, rsn=rsn), kck), 2),  # 3
        eapol_frame(AP, sta, eapol_key(0x030A, replay + 1, bytes(32), b"", kck), 2),  # 4: MIC, secure
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
               tid: int = 0, retry: bool = False, gcmp: bool = False, pad: bytes | None = None,
               a3: str = AP, fragment: int = 0, more: bool = False) -> Packet:
    """A protected QoS data frame: its CCMP header, `plain` encrypted and its 8-byte MIC (12.5.3.3); with
    `gcmp`, GCMP-128's nonce (Address 2 and the packet number) and 16-byte MIC (12.5.5.3); `pad`: the bytes
    that pad its 26-byte header to 28, radiotap's Flags saying so; `fragment`, `more`: a fragment of an MSDU
    (its number, More Fragments: both in the AAD)."""
    fc = ("to_DS" if a1 == AP else "from_DS") + "+protected" + ("+retry" if retry else "") + ("+MF" if more else "")
    hdr = bytes(Dot11(type=2, subtype=8, FCfield=fc, addr1=a1, addr2=a2, addr3=a3, SC=sn << 4 | fragment)
                / Dot11QoS(TID=tid))
    p = pn.to_bytes(6, "little")
    ccmp = bytes((p[0], p[1], 0, 0x20 | key_index << 6)) + p[2:6]
    aad = bytes((hdr[0] & 0x8F, (hdr[1] & 0xC7 | 0x40) & 0x7F)) + hdr[4:22] + bytes((hdr[22] & 0x0F, 0)) + \
        bytes((hdr[24] & 0x0F, 0))
    if gcmp:
        sealed = AESGCM(key).encrypt(mac(a2) + pn.to_bytes(6, "big"), plain, aad)
    else:
        sealed = AESCCM(key, tag_length=8).encrypt(bytes((tid,)) + mac(a2) + pn.to_bytes(6, "big"), plain, aad)
    if pad is None:
        return RadioTap() / Raw(hdr + ccmp + sealed)
    return RadioTap(present="Flags", Flags="pad") / Raw(hdr + pad + ccmp + sealed)
