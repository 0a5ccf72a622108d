"""What a receiver remembers of the air, per capture: 802.11 duplicate detection, the access point's relays,
the MSDUs being reassembled from fragments, and the WPA2 keys (`wpa.py`). `wifi.strip_80211` asks it of
each data frame."""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field

from mavscope.transport.ccmp import WINDOW  # (numbers remembered behind the newest: 802.11ax's block ack window)
from mavscope.transport.wpa import Wpa

MAX_REMEMBERED = 1 << 18  # numbers remembered over all caches (about 40 MB), the least recent caches forgotten


class Retries:
    """802.11 duplicate detection as a receiver does it (IEEE 802.11-2016 10.3.2.14): a frame with the Retry bit
    set whose sequence and fragment number its receiver already has from the same transmitter (per TID for QoS
    data) is a retransmission the receiver discards (its first copy was received; the ACK was lost).
    Retransmissions are common in monitor-mode captures, and their packets would otherwise be shown (and
    counted) twice. A monitor sees what every receiver does, so a cache is kept per receiver (Address 1)
    too: a transmitter numbers its QoS data per receiver and TID, and the same number to two receivers is two
    frames. Under a block ack agreement (802.11n on) a retransmission may come after frames numbered later (its
    A-MPDU's other frames were acknowledged), and the receiver's scoreboard still knows it: so each cache holds
    the numbers up to WINDOW behind the newest, not the last one only; a frame numbered as far from the newest
    as a reset counter (a new association) starts the cache over.

    A retransmission repeats its frame's body byte for byte (an encrypted one its packet number and
    ciphertext too); one with another body is no sender's (`conflict`): the receiver keeps the first."""

    def __init__(self, limit: int = MAX_REMEMBERED) -> None:
        self.limit = limit
        self.caches: OrderedDict[bytes, tuple[int, dict[int, bytes]]] = OrderedDict()  # key -> (newest, sc -> body)
        self.size = 0

    def duplicate(self, key: bytes, sc: int, retry: bool, body: bytes) -> bool | None:
        """None when the frame of cache `key` (receiver, transmitter and TID), Sequence Control `sc` and
        `body` is no duplicate (the cache then holds it), else whether its body is the first copy's."""
        digest = hashlib.blake2b(body, digest_size=16).digest()
        sn = sc >> 4
        got = self.caches.get(key)
        seen: dict[int, bytes]
        if got is None:
            newest, seen = sn, {}
        else:
            self.caches.move_to_end(key)
            newest, seen = got
            behind = (newest - sn) % 4096
            if retry and behind < WINDOW and sc in seen:
                return seen[sc] == digest
            if behind >= WINDOW:  # ahead of the newest (or a counter started over): the window moves
                if (sn - newest) % 4096 >= WINDOW:
                    self.size -= len(seen)
                    seen = {}
                newest = sn
                if len(seen) >= 2 * WINDOW:  # (numbers past the window are never matched: forgotten now and then)
                    old = [k for k in seen if (newest - (k >> 4)) % 4096 >= WINDOW]
                    for k in old:
                        del seen[k]
                    self.size -= len(old)
        if sc not in seen:
            self.size += 1
        seen[sc] = digest
        self.caches[key] = (newest, seen)
        while self.size > self.limit:
            _, (_, gone) = self.caches.popitem(last=False)
            self.size -= len(gone)
        return None


RELAYS_KEPT = 4096  # frames sent to an access point for it to relay, remembered (the oldest forgotten)


class Relays:
    """The access point's relays. In an infrastructure network a station sends a packet for another station
    (or for every station) to the access point (To DS), and the access point sends it on (From DS, the
    original sender as Address 3): a monitor captures the packet twice, and its MAVLink frames would be
    shown and counted twice (a duplicate in every Links table, a seq-duplicate finding). The relay carries
    the same MSDU from the same source to the same destination: it is said and not dissected again."""

    def __init__(self, limit: int = RELAYS_KEPT) -> None:
        self.limit = limit
        self.sent: OrderedDict[bytes, None] = OrderedDict()

    def _key(self, sa: bytes, da: bytes, msdu: bytes) -> bytes:
        return sa + da + hashlib.blake2b(msdu, digest_size=16).digest()

    def to_ap(self, sa: bytes, da: bytes, msdu: bytes) -> None:
        """A frame from `sa` for `da`, sent to the access point."""
        key = self._key(sa, da, msdu)
        self.sent[key] = None
        self.sent.move_to_end(key)
        if len(self.sent) > self.limit:
            self.sent.popitem(last=False)

    def relayed(self, sa: bytes, da: bytes, msdu: bytes) -> bool:
        """Whether a frame from the access point, from `sa` for `da`, relays one sent to it (forgotten then:
        one relay each)."""
        return self.sent.pop(self._key(sa, da, msdu), False) is None


FRAGMENTED_KEPT = 4096  # MSDUs being reassembled, per receiver, transmitter and TID (the least recent dropped)
MAX_FRAGMENT_BYTES = 16 * 11454  # an MSDU's fragments (16 at most, each an MPDU)


@dataclass(slots=True)
class _Partial:
    sc: int  # the last fragment's Sequence Control
    parts: list[bytes]
    records: list[int]
    pn: int | None  # the last fragment's packet number (None: not protected)
    ident: bytes  # the key of its fragments


class Fragments:
    """802.11 defragmentation as a receiver does it (IEEE 802.11-2016 10.6; Linux's mac80211 with the
    FragAttacks fixes of 2021): the fragments of one MSDU, from one transmitter to one receiver in one TID,
    share its sequence number and come in the order of their fragment numbers, the last without More
    Fragments; protected ones carry consecutive packet numbers under one key (12.5.3.4.4), never mixed with
    plaintext ones. A fragment that breaks these is dropped with its MSDU's others (`wifi-fragment`), and so
    is an MSDU a new one replaces before it completes, or that never completes."""

    def __init__(self, limit: int = FRAGMENTED_KEPT) -> None:
        self.limit = limit
        self.partial: OrderedDict[bytes, _Partial] = OrderedDict()

    def add(self, key: bytes, sc: int, more: bool, msdu: bytes, record: int, pn: int | None = None,
            ident: bytes = b"") -> tuple[bytes, tuple[int, ...]] | str | None:
        """A fragment (`pn`, `ident`: its packet number and key, protected): its MSDU and the records of its
        other fragments when it completes one; a message when the receiver drops something (the fragment
        itself, or fragments held before); None when it is held."""
        p = self.partial.pop(key, None)
        if sc & 0xF == 0:
            self.partial[key] = _Partial(sc, [msdu], [record], pn, ident)
            if len(self.partial) > self.limit:
                self.partial.popitem(last=False)
            if p is not None:  # (a new MSDU: the one before never completed)
                return f"802.11 fragments of sequence number {p.sc >> 4} ({_records(p.records)}) never completed: " \
                       "the receiver dropped them when another MSDU began"
            return None if more else self._done(key)
        why = None
        if p is None or p.sc >> 4 != sc >> 4:
            why = "no fragment before it of its MSDU was kept"
        elif sc & 0xF != (p.sc & 0xF) + 1:
            why = f"fragment {sc & 0xF} after fragment {p.sc & 0xF}: out of order"
        elif (pn is None) != (p.pn is None) or ident != p.ident:
            why = "protected and plaintext fragments, or fragments under two keys, mixed (the FragAttacks of 2021)"
        elif pn is not None and p.pn is not None and pn != p.pn + 1:
            why = f"packet number {pn} after {p.pn}: not consecutive"
        elif sum(map(len, p.parts)) + len(msdu) > MAX_FRAGMENT_BYTES:
            why = "longer than 16 MPDUs"
        if why is not None:
            held = f" and the fragments held before it ({_records(p.records)})" if p is not None else ""
            return f"802.11 fragment {sc & 0xF} of sequence number {sc >> 4}: {why}; the receiver drops it{held}"
        assert p is not None
        p.sc, p.pn = sc, pn
        p.parts.append(msdu)
        p.records.append(record)
        self.partial[key] = p
        return None if more else self._done(key)

    def _done(self, key: bytes) -> tuple[bytes, tuple[int, ...]]:
        p = self.partial.pop(key)
        return b"".join(p.parts), tuple(p.records[:-1])

    def flush(self) -> list[tuple[int, str]]:
        """The MSDUs never completed: (their last fragment's record, the message)."""
        out = [(p.records[-1], f"802.11 fragments of sequence number {p.sc >> 4} ({_records(p.records)}) never "
                f"completed: the receiver discarded them") for p in self.partial.values()]
        self.partial.clear()
        return out


def _records(records: list[int]) -> str:
    return ("record " if len(records) == 1 else "records ") + ", ".join(map(str, records[:8])) + \
        (f" and {len(records) - 8} more" if len(records) > 8 else "")


@dataclass(slots=True)
class Air:
    """One capture's 802.11 state."""

    wpa: Wpa | None = None  # the WPA2 handshakes and keys (--wifi-key), None without keys
    retries: Retries = field(default_factory=Retries)
    relays: Relays = field(default_factory=Relays)
    fragments: Fragments = field(default_factory=Fragments)
    record: int = 0  # the number of the record being read (the handshake messages' records are a key's origin)
