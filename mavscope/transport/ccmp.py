"""802.11 frame protection: CCMP-128 and GCMP-128 (IEEE 802.11-2016 12.5.3, 12.5.5) and the receiver's
replay check, for the keys the handshakes of `mavscope.transport.wpa` give.

Both ciphers share the 8-byte header (packet number, extended IV, key index) and the AAD (the header with
its mutable bits masked); CCMP's nonce is the TID, Address 2 and the packet number, with an 8-byte MIC,
GCMP's Address 2 and the packet number, with a 16-byte one.

The replay check is the receiver's: per key, transmitter and TID, packet numbers must increase in the order
of the 802.11 sequence numbers. Under a block ack agreement the receiver reorders a window of frames by
sequence number before it checks them (Linux's mac80211: ieee80211_rx_reorder_ampdu, then the key's check),
so a retransmission that comes after frames numbered later is read; a recorded frame sent again (its
sequence number, which the AAD does not cover, rewritten or not) carries a packet number lower than those
around it and is discarded.
"""

from __future__ import annotations

import hashlib
from typing import NamedTuple

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives.ciphers.aead import AESCCM, AESGCM

CCMP_128, GCMP_128 = 4, 8  # RSN cipher suite selectors 00-0F-AC:4 and :8
CIPHER_NAMES = {1: "WEP-40", 2: "TKIP", 4: "CCMP-128", 5: "WEP-104", 8: "GCMP-128", 9: "GCMP-256", 10: "CCMP-256"}
WINDOW = 256  # sequence numbers a receiver reorders within (802.11ax's block ack window)
MAX_MPDU = 11454  # the longest MPDU (802.11-2016 9.2.4.7.1, VHT): a body longer is no frame a radio sent


def key_ident(tk: bytes, suite: int) -> bytes:
    """What tells one key from another without holding it."""
    return hashlib.sha256(b"mavscope tk" + bytes((suite,)) + tk).digest()[:16]


class TemporalKey:
    """A TK (or GTK) of one cipher, and the packet numbers its receivers accepted."""

    __slots__ = ("cipher", "gcmp", "ident", "numbers", "origin")

    def __init__(self, tk: bytes, suite: int = CCMP_128, origin: tuple[int, ...] = ()) -> None:
        """`origin`: the records of the handshake messages that gave the key."""
        self.origin = origin
        self.gcmp = suite == GCMP_128
        self.cipher: AESCCM | AESGCM = AESGCM(tk) if self.gcmp else AESCCM(tk, tag_length=8)
        self.ident = key_ident(tk, suite)  # (a key installed again)
        self.numbers: dict[bytes, PacketNumbers] = {}  # transmitter + TID -> what was accepted

    def __repr__(self) -> str:
        return "TemporalKey(...)"


class PacketNumbers:
    """The packet numbers accepted from one transmitter and TID under one key, by sequence number: those
    of the sequence numbers up to WINDOW behind the newest, the highest of those before (`floor`), and the
    highest of all (`top`)."""

    __slots__ = ("floor", "newest", "recent", "top")

    def __init__(self, sn: int, pn: int) -> None:
        self.newest, self.floor, self.top = sn, -1, pn
        self.recent: dict[int, int] = {sn: pn}

    def _forget(self, every: bool) -> None:
        """Fold the numbers WINDOW or more behind the newest into `floor`: from the oldest kept while they are
        (they come in order but for reordered ones), or `every` one of them."""
        recent, newest = self.recent, self.newest
        for s in list(recent):
            if (newest - s) % 4096 >= WINDOW:
                self.floor = max(self.floor, recent.pop(s))
            elif not every:
                break

    def accept(self, sn: int, pn: int) -> int | None:
        """None when packet number `pn` of sequence number `sn` is in order (it is then accepted), else
        the accepted packet number it is not above."""
        if pn > self.top:  # above every number accepted: no captured frame's again, whatever its place
            self.top = pn
            if (sn - self.newest) % 4096 < 2048 or (self.newest - sn) % 4096 >= WINDOW:
                self.newest = sn  # (ahead, or far from the window: a gap the monitor missed, a counter restarted)
            self.recent[sn] = pn
            self._forget(len(self.recent) > 2 * WINDOW)
            return None
        if sn in self.recent:
            return self.recent[sn]  # a number already read
        if (self.newest - sn) % 4096 >= WINDOW:
            return self.top  # not above the newest, outside the window a receiver reorders in
        self._forget(True)  # (so that what is left is within the window: before or after, modulo 4096, is sure)
        if pn <= self.floor:
            return self.floor
        for s, p in self.recent.items():  # a frame reordered into the window: between its neighbours
            after = (s - sn) % 4096 < 2048
            if (after and pn >= p) or (not after and pn <= p):
                return p
        self.recent[sn] = pn
        return None


def aad_nonce(data: bytes, off: int, qos: int, pn: int, gcmp: bool) -> tuple[bytes, bytes]:
    """The AAD and nonce of the protected data frame at `off` (`qos`: its QoS Control's offset, 0 without):
    12.5.3.3.3-4 (GCMP's AAD is CCMP's, 12.5.5.3.3). The frame control's Subtype bits 4-6, Retry,
    Power Management and More Data are masked, Protected set, Order masked in QoS data (as hostapd);
    the sequence number masked, the fragment number kept; the QoS Control's TID alone."""
    fc0, fc1 = data[off], data[off + 1]
    fc1 = (fc1 & ~(0x08 | 0x10 | 0x20) | 0x40) & (0x7F if qos else 0xFF)
    aad = bytes((fc0 & 0x8F, fc1)) + data[off + 4:off + 22] + bytes((data[off + 22] & 0x0F, 0))
    if data[off + 1] & 3 == 3:
        aad += data[off + 24:off + 30]
    if qos:
        aad += bytes((data[qos] & 0x0F, 0))
    a2, number = data[off + 10:off + 16], pn.to_bytes(6, "big")
    return aad, (a2 + number if gcmp else bytes(((data[qos] & 0x0F) if qos else 0,)) + a2 + number)


class Plain(NamedTuple):
    """A decrypted frame's plaintext, the records of the handshake messages its key came from, its packet
    number and its key (`ident`: a fragment's must be its MSDU's first's)."""

    data: bytes
    origin: tuple[int, ...]
    pn: int = 0
    ident: bytes = b""


def unprotect(keys: list[TemporalKey], data: bytes, off: int, body: int, end: int,
              qos: int) -> Plain | tuple[str, str]:
    """The plaintext of the protected data frame at `off` whose body (header, ciphertext, MIC) runs from
    `body` to `end`, under the first of `keys` its MIC verifies with; else the code and message of the note
    on a frame the receiver does not read."""
    a1, a2 = data[off + 4:off + 10].hex(":"), data[off + 10:off + 16].hex(":")
    if end - body > MAX_MPDU:
        return ("malformed-packet", f"802.11 protected frame of {end - body} bytes: longer than any frame a radio "
                f"sends ({MAX_MPDU})")
    iv = data[body:body + 8]
    pn = int.from_bytes(bytes((iv[7], iv[6], iv[5], iv[4], iv[1], iv[0])), "big")
    sealed = data[body + 8:end]
    tid = data[qos] & 0x0F if qos else 16
    counter = data[off + 10:off + 16] + bytes((tid,))
    sn = data[off + 23] << 4 | data[off + 22] >> 4
    for k in keys:
        if len(sealed) < (16 if k.gcmp else 8):
            continue
        aad, nonce = aad_nonce(data, off, qos, pn, k.gcmp)
        try:
            plain = k.cipher.decrypt(nonce, sealed, aad)
        except (InvalidTag, ValueError):
            continue
        numbers = k.numbers.get(counter)
        if numbers is None:
            k.numbers[counter] = PacketNumbers(sn, pn)
            return Plain(plain, k.origin, pn, k.ident)
        last = numbers.accept(sn, pn)
        if last is None:
            return Plain(plain, k.origin, pn, k.ident)
        return ("wifi-replay", f"802.11 frame from {a2} to {a1} with packet number {pn} (sequence number {sn}), "
                f"not above the {last} its key accepted in the order of sequence numbers: the receiver discarded "
                "it as a replay")
    return ("wifi-decrypt-failed", f"802.11 frame from {a2} to {a1} whose MIC fails with every key of theirs: the "
            "receiver drops it (forged, damaged, or under a key whose handshake the capture missed)")
