"""WPA2-Personal decryption of 802.11 data frames (CCMP-128), given the network's passphrase or PSK.

A monitor-mode capture of a WPA2 network holds its 4-way handshakes: with the passphrase (or the PSK) the
pairwise keys of each station that associated while the capture ran follow, and from them the group key
the access point sends in message 3. mavscope keeps what a receiving station keeps: the keys of the
handshakes whose MIC verifies (a handshake forged without the passphrase installs nothing), the newest
first, and per key and TID the last packet number it accepted: a frame whose CCMP MIC fails is dropped
(`wifi-decrypt-failed`), and one whose packet number is not above the last is a replay the receiver
discards (`wifi-replay`, which Wireshark does not check).

IEEE 802.11-2016: 12.7.1.2 (PRF), 12.7.1.7.2 (KDF, for the SHA-256 AKM), 12.7.2 (EAPOL-Key frames), 12.7.6
(the 4-way handshake), 12.7.7 (the group key handshake), 12.5.3 (CCMP: its header, nonce and AAD), J.4 (the
passphrase-to-PSK mapping); RFC 3394 (AES key wrap). TKIP (WPA1), GCMP and SAE (WPA3) are not decrypted.
Secrets (passphrases, PSKs, derived keys) are never printed: the keys' reprs and every message leave them out.
"""

from __future__ import annotations

import hashlib
import hmac
import struct
from collections import OrderedDict
from dataclasses import dataclass, field

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives.ciphers.aead import AESCCM
from cryptography.hazmat.primitives.ciphers.algorithms import AES
from cryptography.hazmat.primitives.cmac import CMAC
from cryptography.hazmat.primitives.keywrap import InvalidUnwrap, aes_key_unwrap

from mavscope.errors import UsageError

ETHERTYPE_EAPOL = 0x888E
MAX_PAIRS = 65536  # station pairs kept (with keys; and apart, with nonces only), the least recent forgotten
KEYS_KEPT = 2  # keys per pair or group key index: the newest and the one before (frames in flight on a rekey)

# EAPOL-Key Key Information bits (12.7.2)
KI_VERSION, KI_PAIRWISE, KI_INSTALL, KI_ACK = 0x7, 0x8, 0x40, 0x80
KI_MIC, KI_SECURE, KI_ENCRYPTED = 0x100, 0x200, 0x1000
# EAPOL header (version, type, length), then the key descriptor: type, Key Information, key length, replay
# counter, nonce, IV, RSC, reserved, MIC (16 bytes for the PSK AKMs, at byte 81), key data length
_EAPOL_KEY = struct.Struct("!BBHBHHQ32s16s8s8x16sH")


@dataclass(frozen=True, slots=True)
class WifiKey:
    """A network's PMK (the PSK), from `wpa-pwd:PASSPHRASE:SSID` or `wpa-psk:HEX`. Its repr is its label."""

    label: str  # which option gave it (never the secret)
    pmk: bytes = field(repr=False)


def _ssid(text: str, what: str) -> bytes:
    """An SSID as given: UTF-8, with %XX for any byte (so ':' and '%' can be written)."""
    out = bytearray()
    i = 0
    raw = text.encode("utf-8", "surrogateescape")
    while i < len(raw):
        if raw[i] == 0x25:  # %
            try:
                out.append(int(raw[i + 1:i + 3].decode("ascii"), 16))
            except (ValueError, UnicodeDecodeError):
                raise UsageError(f"{what}: an SSID's % is followed by two hex digits (%3a for ':')") from None
            i += 3
        else:
            out.append(raw[i])
            i += 1
    return bytes(out)


def wifi_key(spec: str, number: int) -> WifiKey:
    """The key of `--wifi-key` number `number` (from 1): `wpa-pwd:PASSPHRASE:SSID` (the SSID after the last
    ':') or `wpa-psk:<64 hex digits>` (UsageError naming what is wrong, never what was given)."""
    what = f"--wifi-key #{number}"
    kind, _, rest = spec.partition(":")
    if kind == "wpa-psk":
        try:
            pmk = bytes.fromhex(rest)
        except ValueError:
            raise UsageError(f"{what}: wpa-psk: takes 64 hex digits") from None
        if len(pmk) != 32:
            raise UsageError(f"{what}: wpa-psk: takes 64 hex digits (32 bytes), got {len(pmk)} bytes")
        return WifiKey(f"{what} (wpa-psk)", pmk)
    if kind == "wpa-pwd":
        passphrase, sep, ssid_text = rest.rpartition(":")
        if not sep:
            raise UsageError(f"{what}: expected wpa-pwd:PASSPHRASE:SSID")
        ssid = _ssid(ssid_text, what)
        try:
            secret = passphrase.encode("ascii")
        except UnicodeEncodeError:
            raise UsageError(f"{what}: a WPA passphrase is printable ASCII") from None
        if not 8 <= len(secret) <= 63 or not all(32 <= b <= 126 for b in secret):
            raise UsageError(f"{what}: a WPA passphrase is 8 to 63 printable ASCII characters, got {len(secret)}")
        if len(ssid) > 32:
            raise UsageError(f"{what}: an SSID is at most 32 bytes, got {len(ssid)}")
        pmk = hashlib.pbkdf2_hmac("sha1", secret, ssid, 4096, 32)  # 802.11-2016 J.4.1
        return WifiKey(f"{what} (wpa-pwd for SSID {ssid!r})", pmk)
    raise UsageError(f"{what}: expected wpa-pwd:PASSPHRASE:SSID or wpa-psk:<64 hex digits>")


def prf(key: bytes, label: bytes, data: bytes, bits: int) -> bytes:
    """PRF-`bits` of 802.11-2016 12.7.1.2 (HMAC-SHA-1)."""
    out = b""
    i = 0
    while len(out) * 8 < bits:
        out += hmac.new(key, label + b"\x00" + data + bytes((i,)), hashlib.sha1).digest()
        i += 1
    return out[:bits // 8]


def kdf_sha256(key: bytes, label: bytes, context: bytes, bits: int) -> bytes:
    """KDF-SHA-256-`bits` of 802.11-2016 12.7.1.7.2."""
    out = b""
    i = 1
    while len(out) * 8 < bits:
        out += hmac.new(key, i.to_bytes(2, "little") + label + context + bits.to_bytes(2, "little"),
                        hashlib.sha256).digest()
        i += 1
    return out[:bits // 8]


def ptk(pmk: bytes, version: int, aa: bytes, spa: bytes, anonce: bytes, snonce: bytes) -> bytes:
    """The 48-byte PTK (KCK, KEK, TK) of a CCMP-128 pair (12.7.1.3): PRF-384, or KDF-SHA-256-384 for key
    descriptor version 3 (the SHA-256 AKM)."""
    data = min(aa, spa) + max(aa, spa) + min(anonce, snonce) + max(anonce, snonce)
    if version == 3:
        return kdf_sha256(pmk, b"Pairwise key expansion", data, 384)
    return prf(pmk, b"Pairwise key expansion", data, 384)


def eapol_mic(kck: bytes, version: int, eapol: bytes) -> bytes:
    """The 16-byte MIC of an EAPOL frame (its MIC field zeroed): HMAC-SHA-1-128 (version 2) or AES-128-CMAC
    (version 3)."""
    if version == 3:
        c = CMAC(AES(kck))
        c.update(eapol)
        return c.finalize()
    return hmac.new(kck, eapol, hashlib.sha1).digest()[:16]


class TemporalKey:
    """A TK and the last packet number its receivers accepted, per transmitter and TID (16: frames without
    QoS): each side of a pair numbers what it sends on a counter of its own."""

    __slots__ = ("cipher", "ident", "last")

    def __init__(self, tk: bytes) -> None:
        self.cipher = AESCCM(tk, tag_length=8)
        self.ident = hashlib.sha256(b"mavscope tk" + tk).digest()[:16]  # to tell a key installed again
        self.last: dict[bytes, int] = {}

    def __repr__(self) -> str:
        return "TemporalKey(...)"


@dataclass(slots=True, repr=False)
class Pair:
    """A station and its access point: the nonces of their handshake, and their keys (newest first)."""

    anonce: bytes | None = None
    snonce: bytes | None = None
    kck: bytes | None = None
    kek: bytes | None = None
    version: int = 2
    keys: list[TemporalKey] = field(default_factory=list)


def _keep(keys: list[TemporalKey], tk: bytes) -> None:
    """Install `tk` as the newest of `keys`, unless it is installed already: a key installed again keeps its
    packet numbers (a receiver that reset them would accept replays: the KRACK attacks, 2017)."""
    new = TemporalKey(tk)
    if any(k.ident == new.ident for k in keys):
        return
    keys.insert(0, new)
    del keys[KEYS_KEPT:]


def gtk_from_key_data(data: bytes) -> tuple[int, bytes] | None:
    """(key index, GTK) of the GTK KDE in decrypted key data (12.7.2: type 0xDD, OUI 00-0F-AC, data type 1)."""
    i = 0
    while i + 2 <= len(data):
        kind, size = data[i], data[i + 1]
        if kind == 0xDD and size == 0 and not any(data[i + 1:]):
            return None  # the padding
        body = data[i + 2:i + 2 + size]
        if len(body) < size:
            return None
        if kind == 0xDD and size >= 6 and body[:4] == b"\x00\x0f\xac\x01":
            gtk = body[6:]
            return (body[4] & 3, gtk) if len(gtk) in (16, 32) else None
        i += 2 + size
    return None


class Wpa:
    """The handshakes and keys of one capture, for the `keys` given."""

    def __init__(self, keys: tuple[WifiKey, ...], limit: int = MAX_PAIRS) -> None:
        self.pmks = tuple(k.pmk for k in keys)
        self.limit = limit
        self.pairs: OrderedDict[bytes, Pair] = OrderedDict()  # (AA + SPA) -> a pair whose handshake verified
        # pairs with a message 1 and no verified message 2 yet, apart: a flood of forged first messages
        # (anyone can send them) forgets these, never the keys of the stations that did associate
        self.pending: OrderedDict[bytes, Pair] = OrderedDict()
        self.groups: OrderedDict[bytes, dict[int, list[TemporalKey]]] = OrderedDict()

    def __repr__(self) -> str:
        return f"Wpa({len(self.pmks)} keys, {len(self.pairs)} pairs)"

    def _pair(self, aa: bytes, spa: bytes, create: bool) -> Pair | None:
        key = aa + spa
        for table in (self.pairs, self.pending):
            p = table.get(key)
            if p is not None:
                table.move_to_end(key)
                return p
        if not create:
            return None
        if len(self.pending) >= self.limit:
            self.pending.popitem(last=False)
        p = self.pending[key] = Pair()
        return p

    def _verified(self, aa: bytes, spa: bytes, pair: Pair) -> None:
        """`pair`'s message 2 verified: it holds keys from now on."""
        key = aa + spa
        self.pending.pop(key, None)
        if key not in self.pairs and len(self.pairs) >= self.limit:
            self.pairs.popitem(last=False)
        self.pairs[key] = pair
        self.pairs.move_to_end(key)

    def eapol(self, a1: bytes, a2: bytes, eapol: bytes) -> None:
        """An EAPOL frame from `a2` to `a1` (its bytes from the EAPOL header on): a handshake message."""
        if len(eapol) < _EAPOL_KEY.size:
            return
        (_, ptype, length, desc, info, _, _, nonce, _, _, mic, kd_len) = _EAPOL_KEY.unpack_from(eapol)
        end = 4 + length
        if ptype != 3 or desc != 2 or end > len(eapol) or _EAPOL_KEY.size + kd_len > end:
            return  # not an RSN EAPOL-Key frame (WPA1's descriptor 254 is TKIP's)
        version = info & KI_VERSION
        if version not in (2, 3):
            return
        frame = eapol[:end]
        zeroed = frame[:81] + bytes(16) + frame[97:]
        key_data = frame[_EAPOL_KEY.size:_EAPOL_KEY.size + kd_len]
        ack = info & KI_ACK
        aa, spa = (a2, a1) if ack else (a1, a2)  # the authenticator (the access point) sends the ACKed ones
        pair = self._pair(aa, spa, create=bool(ack and info & KI_PAIRWISE and not info & KI_MIC))
        if pair is None:
            return
        if not info & KI_PAIRWISE:  # group key message 1: the new GTK under the pair's KEK
            if ack and info & KI_MIC and pair.kck is not None and hmac.compare_digest(
                    eapol_mic(pair.kck, pair.version, zeroed), mic):
                self._group(aa, pair, key_data, info)
            return
        if ack and not info & KI_MIC:  # message 1
            pair.anonce = nonce
            return
        if not ack and info & KI_MIC and not info & KI_SECURE and any(nonce):  # message 2: find the PMK
            if pair.anonce is None:
                return
            for pmk in self.pmks:
                keys = ptk(pmk, version, aa, spa, pair.anonce, nonce)
                if hmac.compare_digest(eapol_mic(keys[:16], version, zeroed), mic):
                    pair.snonce, pair.kck, pair.kek, pair.version = nonce, keys[:16], keys[16:32], version
                    _keep(pair.keys, keys[32:48])
                    self._verified(aa, spa, pair)
                    return
            return
        if ack and info & KI_MIC and info & KI_INSTALL and pair.kck is not None:  # message 3: the GTK
            if hmac.compare_digest(eapol_mic(pair.kck, pair.version, zeroed), mic):
                self._group(aa, pair, key_data, info)

    def _group(self, aa: bytes, pair: Pair, key_data: bytes, info: int) -> None:
        if not info & KI_ENCRYPTED or pair.kek is None or len(key_data) < 24 or len(key_data) % 8:
            return
        try:
            plain = aes_key_unwrap(pair.kek, key_data)
        except InvalidUnwrap:
            return
        found = gtk_from_key_data(plain)
        if found is None or len(found[1]) != 16:  # (a 32-byte GTK is GCMP-256's)
            return
        index, gtk = found
        groups = self.groups.get(aa)
        if groups is None:
            if len(self.groups) >= self.limit:
                self.groups.popitem(last=False)
            groups = self.groups[aa] = {}
        _keep(groups.setdefault(index, []), gtk)

    def keys_for(self, a1: bytes, a2: bytes, index: int) -> list[TemporalKey] | None:
        """The keys a frame from `a2` to `a1` may be under (group-addressed: the GTKs of index `index` of its
        access point `a2`; else the pair's), None when there are none."""
        if a1[0] & 1:
            groups = self.groups.get(a2)
            return None if groups is None else groups.get(index) or None
        p = self.pairs.get(a2 + a1)
        if p is None or not p.keys:
            p = self.pairs.get(a1 + a2)
        return None if p is None or not p.keys else p.keys

    def decrypt(self, data: bytes, off: int, body: int, end: int, qos: int) -> bytes | tuple[str, str]:
        """The plaintext of the protected data frame at `off` whose body (CCMP header, ciphertext, MIC) runs
        from `body` to `end` (`qos`: the offset of its QoS Control field, 0 without), or the code and message
        of the note on a frame the receiver does not read."""
        if end - body < 17:
            return ("malformed-packet", f"802.11 protected frame of {end - body} bytes: shorter than CCMP's "
                    "header and MIC")
        iv = data[body:body + 8]
        if not iv[3] & 0x20:
            return ("wifi-undecoded", "802.11 frame protected with WEP (no extended IV): not decrypted")
        a1, a2 = data[off + 4:off + 10], data[off + 10:off + 16]
        keys = self.keys_for(a1, a2, iv[3] >> 6)
        if keys is None:
            return ("wifi-undecoded", "802.11 frame protected (WPA2/WPA3) between "
                    f"{a2.hex(':')} and {a1.hex(':')}: no key for it (no 4-way handshake of theirs with a given "
                    "--wifi-key seen before it)")
        pn = int.from_bytes(bytes((iv[7], iv[6], iv[5], iv[4], iv[1], iv[0])), "big")
        tid = data[qos] & 0x0F if qos else 16
        nonce = bytes((tid & 0x0F,)) + a2 + pn.to_bytes(6, "big")
        fc0, fc1 = data[off], data[off + 1]
        fc1 = (fc1 & ~(0x08 | 0x10 | 0x20) | 0x40) & (0x7F if qos else 0xFF)  # Retry, PwrMgt, MoreData; Order in QoS
        aad = bytes((fc0 & 0x8F, fc1)) + data[off + 4:off + 22] + bytes((data[off + 22] & 0x0F, 0))
        if data[off + 1] & 3 == 3:
            aad += data[off + 24:off + 30]
        if qos:
            aad += bytes((data[qos] & 0x0F, 0))
        sealed = data[body + 8:end]
        for k in keys:
            try:
                plain = k.cipher.decrypt(nonce, sealed, aad)
            except InvalidTag:
                continue
            counter = a2 + bytes((tid,))
            last = k.last.get(counter)
            if last is not None and pn <= last:
                return ("wifi-replay", f"802.11 frame from {a2.hex(':')} to {a1.hex(':')} with CCMP packet number "
                        f"{pn}, not above the {last} its key last accepted: the receiver discarded it as a replay")
            k.last[counter] = pn
            return plain
        return ("wifi-decrypt-failed", f"802.11 frame from {a2.hex(':')} to {a1.hex(':')} whose CCMP MIC fails "
                "with every key of theirs: the receiver drops it (forged, damaged, or under a key whose handshake "
                "the capture missed)")
