"""WPA2-Personal decryption of 802.11 data frames, given the network's passphrase or PSK: the handshakes.

A monitor-mode capture of a WPA2 network holds its 4-way handshakes: with the passphrase (or the PSK) the
pairwise keys of each station that associated while the capture ran follow, and from them the group key
the access point sends in message 3. mavscope takes each message as the station and the access point take
it (wpa_supplicant, hostapd): replay counters that only increase, message 2 paired with the message 1 of
its counter and verified by its MIC (a handshake forged without the passphrase installs nothing), the
ciphers the station's RSNE chose. The frames are decrypted and their packet numbers checked by `ccmp.py`.

IEEE 802.11-2016: 12.7.1.2 (PRF), 12.7.1.7.2 (KDF, for the SHA-256 AKM), 12.7.2 (EAPOL-Key frames), 12.7.6
(the 4-way handshake), 12.7.7 (the group key handshake), 9.4.2.25 (the RSNE), J.4 (the passphrase-to-PSK
mapping); RFC 3394 (AES key wrap). TKIP (WPA1), 256-bit ciphers and SAE (WPA3) are not decrypted.
Secrets (passphrases, PSKs, derived keys) are never printed: the keys' reprs and every message leave them out.
"""

from __future__ import annotations

import hashlib
import hmac
import struct
from collections import OrderedDict
from dataclasses import dataclass, field

from cryptography.hazmat.primitives.ciphers.algorithms import AES
from cryptography.hazmat.primitives.cmac import CMAC
from cryptography.hazmat.primitives.keywrap import InvalidUnwrap, aes_key_unwrap

from mavscope.errors import UsageError
from mavscope.notes import GivenUp, Note, pop_newest
from mavscope.transport.ccmp import CCMP_128, CIPHER_NAMES, GCMP_128, Plain, TemporalKey, key_ident, unprotect

ETHERTYPE_EAPOL = 0x888E
MAX_PAIRS = 65536  # station pairs kept (with keys; and apart, with nonces only), the newest forgotten (said)
KEYS_KEPT = 2  # keys per pair or group key index: the newest and the one before (frames in flight on a rekey)
ANONCES_KEPT = 4  # message 1s of a pair whose message 2 may still come (a forged one among them changes nothing)
SEEN_KEPT = 64  # keys a pair installed, remembered so that a replayed handshake cannot install one again
SUITES = (CCMP_128, GCMP_128)  # the ciphers decrypted (both with 16-byte keys)

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
            raise UsageError(f"{what}: a WPA passphrase is 8 to 63 printable ASCII characters")
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


@dataclass(slots=True, repr=False)
class Pair:
    """A station and its access point: their handshake's nonces and counters, and their keys (newest first)."""

    anonces: list[tuple[tuple[int, ...], bytes]] = field(default_factory=list)  # (records, ANonce) of message 1s
    replay: int = -1  # the highest replay counter of a message the station verified (12.7.2: never lower again)
    kck: bytes | None = None
    kek: bytes | None = None
    version: int = 2
    pairwise: int = CCMP_128  # the cipher suites the station chose (its RSNE in message 2)
    group: int = CCMP_128
    keys: list[TemporalKey] = field(default_factory=list)
    seen: list[bytes] = field(default_factory=list)  # every key the pair installed (the last SEEN_KEPT)
    origin: tuple[int, ...] = ()  # the records of the messages 1 and 2 that gave its newest key
    left: bool = False  # an association of theirs ended or began since their last handshake
    epoch: int = 0  # their access point's broadcast deauthentications when they last verified a handshake


def _keep(keys: list[TemporalKey], tk: bytes, suite: int, seen: list[bytes] | None = None,
          origin: tuple[int, ...] = ()) -> None:
    """Install `tk` as the newest of `keys`, unless it is installed already, or (`seen`) was once: a key
    installed again keeps its packet numbers (a receiver that reset them would accept replays: the KRACK
    attacks, 2017), and a handshake's nonces are never used twice, so a key that comes back is a recorded
    handshake sent again."""
    new = TemporalKey(tk, suite, origin)
    if any(k.ident == new.ident for k in keys) or (seen is not None and new.ident in seen):
        return
    if seen is not None:
        seen.append(new.ident)
        del seen[:-SEEN_KEPT]
    keys.insert(0, new)
    del keys[KEYS_KEPT:]


def rsne_suites(key_data: bytes) -> tuple[int, int] | None:
    """(group, pairwise) cipher suite types of the RSNE in message 2's key data (9.4.2.25: version, group
    suite, pairwise count and suites), None without one (or with suites of another OUI: 0 then)."""
    i = 0
    while i + 2 <= len(key_data):
        kind, size = key_data[i], key_data[i + 1]
        body = key_data[i + 2:i + 2 + size]
        if kind == 0x30 and len(body) >= 12 and body[6] | body[7] << 8 >= 1:
            def suite(at: int) -> int:
                return body[at + 3] if body[at:at + 3] == b"\x00\x0f\xac" else 0
            return suite(2), suite(8)
        i += 2 + size
    return None


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
        self.said: list[Note] = []  # what the bounds gave up (`capacity` notes), for the record being read
        self.gave_up = {table: GivenUp(f"WPA2 {what} (at most {limit:,})", unit, self.said) for table, what, unit in (
            ("pending", "handshakes begun", "message 1s"), ("pairs", "station pairs with keys", "pairs"),
            ("groups", "access points with group keys", "access points"))}
        self.pairs: OrderedDict[bytes, Pair] = OrderedDict()  # (AA + SPA) -> a pair whose handshake verified
        # pairs with a message 1 and no verified message 2 yet, apart: a flood of forged first messages
        # (anyone can send them) forgets these, never the keys of the stations that did associate
        self.pending: OrderedDict[bytes, Pair] = OrderedDict()
        self.groups: OrderedDict[bytes, dict[int, list[TemporalKey]]] = OrderedDict()
        self.group_suites: dict[bytes, int] = {}  # access point -> its group cipher, once a GTK came
        self.epochs: dict[bytes, int] = {}  # access point of a verified pair -> its broadcast deauthentications

    def __repr__(self) -> str:
        return f"Wpa({len(self.pmks)} keys, {len(self.pairs)} pairs)"

    def _pair(self, aa: bytes, spa: bytes, create: bool) -> Pair | None:
        key = aa + spa
        for table in (self.pairs, self.pending):  # (kept in the order they came: the bounds forget the newest)
            p = table.get(key)
            if p is not None:
                return p
        if not create:
            return None
        p = self.pending[key] = Pair()
        if len(self.pending) > self.limit:  # the newest go: a flood of first messages forgets its own
            gone, _ = pop_newest(self.pending, key)
            self.gave_up["pending"].add(f"forgot the handshake begun between {gone[:6].hex(':')} and "
                                        f"{gone[6:].hex(':')}: if it completes, its frames are not decrypted")
        return p

    def _verified(self, aa: bytes, spa: bytes, pair: Pair) -> None:
        """`pair`'s message 2 verified: it holds keys from now on."""
        pair.left, pair.epoch = False, self.epochs.setdefault(aa, 0)
        key = aa + spa
        self.pending.pop(key, None)
        self.pairs[key] = pair
        if len(self.pairs) > self.limit:  # the newest other than this one go: the keys held before a flood stay
            gone, _ = pop_newest(self.pairs, key)
            self.gave_up["pairs"].add(f"forgot the keys of {gone[:6].hex(':')} and {gone[6:].hex(':')}: their "
                                      "later frames are not decrypted")

    def eapol(self, a1: bytes, a2: bytes, eapol: bytes, records: tuple[int, ...] = ()) -> None:
        """An EAPOL frame from `a2` to `a1` (its bytes from the EAPOL header on; in the capture's `records`,
        which a frame decrypted with what it gives names): a handshake message, taken as
        the station and the access point take it (wpa_supplicant, hostapd): message 1 only with a replay
        counter above every verified one since the pair's association began; message 2 (told from 4 by its key
        data, as hostapd tells them: a station sets Secure in both once it has keys) for a message 1 kept, its
        MIC finding the PMK; messages 3 and group message 1 with their MIC and a counter above the last
        verified."""
        if len(eapol) < _EAPOL_KEY.size:
            return
        (_, ptype, length, desc, info, _, counter, nonce, _, _, mic, kd_len) = _EAPOL_KEY.unpack_from(eapol)
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
        first = bool(ack and info & KI_PAIRWISE and not info & KI_MIC)
        pair = self._pair(aa, spa, create=first)
        if pair is None:
            return
        if pair.epoch < self.epochs.get(aa, 0):  # every station of the access point was sent away since
            self._left(pair)
        if first:  # message 1
            if counter > pair.replay:
                pair.anonces = [*pair.anonces, (records, nonce)][-ANONCES_KEPT:]
            return
        if not ack and info & KI_MIC and info & KI_PAIRWISE:
            if kd_len:
                self._message2(aa, spa, pair, version, nonce, key_data, zeroed, mic, records)
            return  # (message 4 holds no key data)
        if not ack or not info & KI_MIC or pair.kck is None or counter <= pair.replay:
            return
        if not hmac.compare_digest(eapol_mic(pair.kck, pair.version, zeroed), mic):
            return
        if info & KI_PAIRWISE and not info & KI_INSTALL:
            return
        pair.replay = counter  # message 3, or group message 1: the GTK under the pair's KEK
        self._group(aa, pair, key_data, info, records)

    def _message2(self, aa: bytes, spa: bytes, pair: Pair, version: int, snonce: bytes, key_data: bytes,
                  zeroed: bytes, mic: bytes, records: tuple[int, ...]) -> None:
        for first, anonce in reversed(pair.anonces):  # (hostapd takes any of the counters it sent lately: each
            for pmk in self.pmks:                  # message 1 kept is tried, its MIC rules a forged one out)
                keys = ptk(pmk, version, aa, spa, anonce, snonce)
                if hmac.compare_digest(eapol_mic(keys[:16], version, zeroed), mic):
                    group, pairwise = rsne_suites(key_data) or (CCMP_128, CCMP_128)
                    ident = key_ident(keys[32:48], pairwise)
                    if ident in pair.seen and (not pair.keys or pair.keys[0].ident != ident):
                        return  # a handshake recorded before and sent again: nothing of it is taken
                    pair.kck, pair.kek, pair.version = keys[:16], keys[16:32], version
                    pair.anonces = []
                    pair.group, pair.pairwise = group, pairwise
                    if pair.left:  # a new association: the keys of the one before are gone (kept till now in
                        pair.keys = []  # case its end was forged, as a deauthentication can be by anyone)
                    pair.origin = tuple(sorted({*first, *records}))
                    if pair.pairwise in SUITES:
                        _keep(pair.keys, keys[32:48], pair.pairwise, pair.seen, pair.origin)
                    else:
                        pair.keys = []
                    self._verified(aa, spa, pair)
                    return

    def _group(self, aa: bytes, pair: Pair, key_data: bytes, info: int, records: tuple[int, ...]) -> None:
        """The GTK in the verified message's `key_data` (wrapped under the pair's KEK), installed for `aa`."""
        if not info & KI_ENCRYPTED or pair.kek is None or len(key_data) < 24 or len(key_data) % 8:
            return
        try:
            plain = aes_key_unwrap(pair.kek, key_data)
        except InvalidUnwrap:
            return
        found = gtk_from_key_data(plain)
        if found is None:
            return
        index, gtk = found
        groups = self.groups.get(aa)
        if groups is None:
            groups = self.groups[aa] = {}
            if len(self.groups) > self.limit:  # (the newest other than this one go)
                gone, _ = pop_newest(self.groups, aa)
                self.gave_up["groups"].add(f"forgot the group keys of {gone.hex(':')}: its later group-addressed "
                                           "frames are not decrypted")
        if pair.group in SUITES and len(gtk) == 16:
            _keep(groups.setdefault(index, []), gtk, pair.group, origin=tuple(sorted({*pair.origin, *records})))
        else:
            groups[index] = []
        self.group_suites[aa] = pair.group

    @staticmethod
    def _left(pair: Pair) -> None:
        """An association of the pair began or ended: its replay counters start over (wpa_supplicant clears
        its own on every association, hostapd's state is new), and what it sends unprotected is no longer
        dropped. Its keys stay until a new handshake verifies (anyone can send a deauthentication: a forged
        one ends nothing), and the keys it ever installed are remembered (a replayed handshake installs none)."""
        pair.replay, pair.anonces, pair.left = -1, [], True

    def association(self, a1: bytes, a2: bytes) -> None:
        """An authentication, (re)association, deauthentication or disassociation frame from `a2` to `a1`
        (to every station, when `a1` is group-addressed)."""
        if a1[0] & 1:
            if a2 in self.epochs:
                self.epochs[a2] += 1
            return
        for key in (a1 + a2, a2 + a1):
            for table in (self.pairs, self.pending):
                p = table.get(key)
                if p is not None:
                    self._left(p)

    def _pair_of(self, a1: bytes, a2: bytes) -> Pair | None:
        p = self.pairs.get(a2 + a1)
        return p if p is not None else self.pairs.get(a1 + a2)

    def protected(self, a1: bytes, a2: bytes) -> bool:
        """Whether frames from `a2` to `a1` travel protected: their pair (or, group-addressed, their access
        point's group) has keys from a verified handshake, so a receiver drops what is not (mac80211's
        ieee80211_drop_unencrypted; EAPOL alone passes)."""
        if a1[0] & 1:
            return a2 in self.group_suites
        p = self._pair_of(a1, a2)
        if p is None or p.left:
            return False
        for aa in (a1, a2):
            if aa in self.epochs:
                return p.epoch >= self.epochs[aa]
        return True

    def decrypt(self, data: bytes, off: int, body: int, end: int, qos: int,
                whole: bool = True) -> Plain | tuple[str, str]:
        """The plaintext of the protected data frame at `off` whose body (its cipher's header, ciphertext, MIC)
        runs from `body` to `end` (`qos`: the offset of its QoS Control field, 0 without; `whole`: not cut by
        the capture's snap length), or the code and message of the note on a frame the receiver does not read."""
        a1, a2 = data[off + 4:off + 10], data[off + 10:off + 16]
        between = f"between {a2.hex(':')} and {a1.hex(':')}"
        if end - body < 16:
            return ("malformed-packet", f"802.11 protected frame of {end - body} bytes: shorter than a cipher's "
                    "header and MIC")
        if not data[body + 3] & 0x20:
            return ("wifi-undecoded", "802.11 frame protected with WEP (no extended IV): not decrypted")
        if a1[0] & 1:  # group-addressed: the access point's group key of the frame's index
            known = a2 in self.group_suites
            suite, keys = self.group_suites.get(a2, CCMP_128), self.groups.get(a2, {}).get(data[body + 3] >> 6)
        else:
            pair = self._pair_of(a1, a2)
            known = pair is not None
            suite, keys = (pair.pairwise, pair.keys) if pair is not None else (0, None)
        if not keys:
            if known and suite and suite not in SUITES:
                why = f"its cipher is {CIPHER_NAMES.get(suite, f'suite {suite}')}, which mavscope does not decrypt"
            else:
                why = "no key for it (no 4-way handshake of theirs with a given --wifi-key seen before it)"
            return ("wifi-undecoded", f"802.11 frame protected (WPA2/WPA3) {between}: {why}")
        if not whole:
            return ("wifi-undecoded", f"802.11 frame protected {between}, cut short by the capture's snap length: "
                    "not decrypted")
        return unprotect(keys, data, off, body, end, qos)
