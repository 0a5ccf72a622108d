"""What a receiver remembers of the air, per capture: 802.11 duplicate detection, the access point's relays,
the MSDUs being reassembled from fragments, and the WPA2 keys (`wpa.py`). `wifi.strip_80211` asks it of
each data frame."""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import NamedTuple

from mavscope.notes import GivenUp, Note, pop_newest
from mavscope.transport.ccmp import MAX_MPDU, WINDOW  # (WINDOW: 802.11ax's block ack window)
from mavscope.transport.defrag import records_text
from mavscope.transport.wpa import Wpa

MAX_REMEMBERED = 1 << 18  # numbers remembered over all caches (about 40 MB), the least recent young caches forgotten
ESTABLISHED = 16  # frames a cache has seen before it is established (forgotten only when no young one is left)


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
    ciphertext too); one with another body is no sender's (`conflict`): the receiver keeps the first.

    The numbers remembered are bounded (MAX_REMEMBERED over all caches). A flood of frames from made-up
    transmitters makes new caches, so they are young until they have seen ESTABLISHED frames, and the bound
    forgets the least recent young cache first: a flood forgets its own, never the caches of the stations that
    were talking before it (a forgotten cache lets a retransmission, or a forged one, be shown as a frame).
    Each forgetting is said (`capacity`)."""

    def __init__(self, limit: int = MAX_REMEMBERED, said: list[Note] | None = None) -> None:
        self.limit = limit
        # key -> (newest, sc -> body, frames seen): the established caches, and the young ones apart
        self.caches: OrderedDict[bytes, tuple[int, dict[int, bytes], int]] = OrderedDict()
        self.young: OrderedDict[bytes, tuple[int, dict[int, bytes], int]] = OrderedDict()
        self.size = 0
        self.given_up = GivenUp(f"802.11 duplicate detection (at most {limit:,} sequence numbers held)",
                                "sequence numbers", said)

    def duplicate(self, key: bytes, sc: int, retry: bool, body: bytes) -> bool | None:
        """None when the frame of cache `key` (receiver, transmitter and TID), Sequence Control `sc` and
        `body` is no duplicate (the cache then holds it), else whether its body is the first copy's."""
        digest = hashlib.blake2b(body, digest_size=16).digest()
        sn = sc >> 4
        table = self.caches
        got = table.get(key)
        if got is None:
            table = self.young
            got = table.get(key)
        seen: dict[int, bytes]
        if got is None:
            newest, seen, frames = sn, {}, 0
        else:
            table.move_to_end(key)
            newest, seen, frames = got
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
        frames += 1
        if table is self.young and frames >= ESTABLISHED:
            del self.young[key]
            table = self.caches
        table[key] = (newest, seen, frames)
        while self.size > self.limit:
            pool = self.young if self.young and next(iter(self.young)) != key else self.caches
            if not pool or next(iter(pool)) == key:
                break
            gone_key, (_, gone, n) = pool.popitem(last=False)
            self.size -= len(gone)
            self.given_up.add(f"forgot the frames of {gone_key[6:12].hex(':')} to {gone_key[:6].hex(':')} "
                              f"({'established' if pool is self.caches else 'young'}: {n:,} seen), so a "
                              "retransmission of theirs is shown as a frame", len(gone))
        return None


RELAYS_KEPT = 4096  # frames sent to an access point for it to relay, remembered (the oldest forgotten)


class Relays:
    """The access point's relays. In an infrastructure network a station sends a packet for another station
    (or for every station) to the access point (To DS), and the access point sends it on (From DS, the
    original sender as Address 3): a monitor captures the packet twice, and its MAVLink frames would be
    shown and counted twice (a duplicate in every Links table, a seq-duplicate finding). The relay carries
    the same MSDU from the same source to the same destination: it is said and not dissected again.

    The frames remembered are bounded (RELAYS_KEPT), the oldest forgotten: a relay of a forgotten frame is
    shown again (a duplicate, never a frame hidden), and each forgetting is said (`capacity`)."""

    def __init__(self, limit: int = RELAYS_KEPT, said: list[Note] | None = None) -> None:
        self.limit = limit
        self.sent: OrderedDict[bytes, None] = OrderedDict()
        self.given_up = GivenUp(f"802.11 relays (at most {limit:,} frames sent to an access point remembered)",
                                "frames", said)

    def _key(self, sa: bytes, da: bytes, msdu: bytes) -> bytes:
        return sa + da + hashlib.blake2b(msdu, digest_size=16).digest()

    def to_ap(self, sa: bytes, da: bytes, msdu: bytes) -> None:
        """A frame from `sa` for `da`, sent to the access point."""
        key = self._key(sa, da, msdu)
        self.sent[key] = None
        self.sent.move_to_end(key)
        if len(self.sent) > self.limit:
            gone, _ = self.sent.popitem(last=False)
            self.given_up.add(f"forgot a frame from {gone[:6].hex(':')} to {gone[6:12].hex(':')}, so the access "
                              "point's relay of it is shown as a second copy")

    def relayed(self, sa: bytes, da: bytes, msdu: bytes) -> bool:
        """Whether a frame from the access point, from `sa` for `da`, relays one sent to it (forgotten then:
        one relay each)."""
        return self.sent.pop(self._key(sa, da, msdu), False) is None


FRAGMENT_SLOTS = 4  # MSDUs a station reassembles at once (mac80211's IEEE80211_FRAGMENT_MAX)
FRAGMENT_LIFETIME = 2.0  # seconds an MSDU's fragments are held (mac80211: 2 s from the first fragment)
MAX_FRAGMENT_HELD = 4 << 20  # fragment bytes held over all stations, FRAGMENT_COST each besides its bytes (as Linux's
# ipfrag_high_thresh); expired MSDUs dropped first, then the most recent stations'
FRAGMENT_COST = 256  # what a fragment held costs besides its bytes (its record and bookkeeping)


class Reassembly(NamedTuple):
    """What a fragment did: the MSDU it completed (the first fragment's header, the MSDU, the records of its
    other fragments), or the code and message of why the receiver dropped it; and what of the MSDUs held
    before it the receiver dropped meanwhile (`said`, each a `wifi-fragment` message)."""

    said: list[str]
    done: tuple[bytes, bytes, tuple[int, ...]] | None = None
    refused: tuple[str, str] | None = None


@dataclass(slots=True)
class _Partial:
    tid: int
    sc: int  # the last fragment's Sequence Control
    header: bytes  # the first fragment's 802.11 header (the frame rebuilt carries it)
    parts: list[bytes]
    records: list[int]
    pn: int | None  # the last fragment's packet number (None: not protected)
    ident: bytes  # the key of its fragments
    time: float | None  # its first fragment's

    @property
    def size(self) -> int:
        """What it counts against MAX_FRAGMENT_HELD."""
        return sum(map(len, self.parts)) + FRAGMENT_COST * len(self.parts)


class Fragments:
    """802.11 defragmentation as a receiver does it (IEEE 802.11-2016 10.6; Linux's mac80211,
    ieee80211_rx_h_defragment, with the FragAttacks fixes of 2021): a station reassembles up to four MSDUs
    at once, each from the fragments of one sequence number and TID in the order of their fragment numbers,
    the last without More Fragments, within 2 s of the first; protected fragments carry consecutive packet
    numbers under one key (12.5.3.4.4), never mixed with plaintext ones; group-addressed frames are never
    fragmented. A fragment that breaks a rule is dropped alone (its MSDU stays held); an MSDU pushed out by a
    fifth, expired or never completed is dropped whole: each is said (`wifi-fragment`).

    What is held is bounded (MAX_FRAGMENT_HELD over all stations, mavscope's bound: a receiver has none over
    its stations): past it, MSDUs of the least recent stations that are past their lifetime go first (the
    receiver dropped those too), then the most recent stations' MSDUs, never those of the station whose
    fragment it is: a flood of fragments from made-up stations pushes out its own, not the MSDU a station was
    sending before it. What the bound drops is said (`capacity`)."""

    def __init__(self, limit: int = MAX_FRAGMENT_HELD, said: list[Note] | None = None) -> None:
        self.limit = limit
        self.stations: OrderedDict[bytes, list[_Partial]] = OrderedDict()  # receiver + transmitter -> MSDUs
        self.held = 0
        self.given_up = GivenUp(f"802.11 reassembly (at most {limit:,} bytes of fragments held)", "bytes", said)

    def add(self, station: bytes, tid: int, sc: int, more: bool, header: bytes, msdu: bytes, record: int,
            time: float | None, pn: int | None = None, ident: bytes = b"") -> Reassembly:
        """A fragment from `station` (receiver and transmitter) in `tid` (`header`: its 802.11 header; `pn`,
        `ident`: its packet number and key, protected): the MSDU it completes, or why the receiver drops it,
        and what it dropped of the MSDUs held before."""
        said: list[str] = []
        frag, sn = sc & 0xF, sc >> 4
        slots = self.stations.pop(station, [])
        for p in [p for p in slots if p.time is not None and time is not None and time - p.time > FRAGMENT_LIFETIME]:
            self._drop(slots, p, f"expired ({FRAGMENT_LIFETIME:g} s after the first)", said)
        what = f"802.11 fragment {frag} of sequence number {sn}"
        try:
            if len(msdu) > MAX_MPDU:
                return Reassembly(said, refused=("wifi-fragment", f"{what} of {len(msdu)} bytes: longer than any "
                                                 "frame a radio sends; the receiver drops it"))
            if frag == 0:
                if len(slots) == FRAGMENT_SLOTS:
                    self._drop(slots, slots[0], f"pushed out by a {FRAGMENT_SLOTS + 1}th MSDU being reassembled",
                               said)
                p = _Partial(tid, sc, header, [msdu], [record], pn, ident, time)
            else:
                found = next((p for p in slots if p.tid == tid and p.sc >> 4 == sn and (p.sc & 0xF) + 1 == frag),
                             None)
                if found is None:
                    return Reassembly(said, refused=("wifi-fragment", f"{what}: no fragment before it of its MSDU is "
                                                     "held; the receiver drops it"))
                if (pn is None) != (found.pn is None) or ident != found.ident:
                    return Reassembly(said, refused=("wifi-fragment-mixed", f"{what}: protected and plaintext "
                                                     "fragments, or fragments under two keys, mixed in one MSDU; the "
                                                     "receiver drops it"))
                if pn is not None and found.pn is not None and pn != found.pn + 1:
                    return Reassembly(said, refused=("wifi-fragment-mixed", f"{what}: packet number {pn} after "
                                                     f"{found.pn}, not consecutive; the receiver drops it"))
                p = found
                slots.remove(p)
                p.sc, p.pn = sc, pn
                p.parts.append(msdu)
                p.records.append(record)
            if not more:
                self.held -= p.size - len(msdu) - FRAGMENT_COST
                return Reassembly(said, (p.header, b"".join(p.parts), tuple(p.records[:-1])))
            slots.append(p)
            self.held += len(msdu) + FRAGMENT_COST
            return Reassembly(said)
        finally:
            if slots:
                self.stations[station] = slots  # (the most recent last)
                self._cap(station, time, said)

    def _drop(self, slots: list[_Partial], p: _Partial, why: str, said: list[str]) -> None:
        slots.remove(p)
        self.held -= p.size
        said.append(_gone(p, why))

    def _cap(self, keep: bytes, time: float | None, said: list[str]) -> None:
        """While more is held than the bound: the least recent stations' MSDUs whose lifetime is over (the
        receiver dropped them), then the most recent stations' MSDUs, the newest first (never `keep`'s)."""
        while self.held > self.limit and time is not None:
            station = next(iter(self.stations))
            slots = self.stations[station]
            if station == keep or any(p.time is None or time - p.time <= FRAGMENT_LIFETIME for p in slots):
                break
            del self.stations[station]
            for p in list(slots):
                self._drop(slots, p, f"expired ({FRAGMENT_LIFETIME:g} s after the first)", said)
        while self.held > self.limit and len(self.stations) > 1:
            station, slots = pop_newest(self.stations, keep)
            p = slots.pop()
            self.held -= p.size
            self.given_up.add(f"dropped the 802.11 fragments of sequence number {p.sc >> 4} "
                              f"({records_text(p.records)}), which a receiver reads: their MSDU is not shown", p.size)
            if slots:  # (back in its place: the most recent but one)
                self.stations[station] = slots
                self.stations.move_to_end(keep)

    def flush(self) -> list[tuple[int, str]]:
        """The MSDUs never completed: (their last fragment's record, the message)."""
        out = [(p.records[-1], _gone(p, "never completed")) for slots in self.stations.values() for p in slots]
        self.stations.clear()
        self.held = 0
        return out


def _gone(p: _Partial, why: str) -> str:
    return f"802.11 fragments of sequence number {p.sc >> 4} ({records_text(p.records)}) {why}: the receiver " \
        "discarded them"


@dataclass(slots=True)
class Air:
    """One capture's 802.11 state."""

    wpa: Wpa | None = None  # the WPA2 handshakes and keys (--wifi-key), None without keys
    retries: Retries = field(init=False)
    relays: Relays = field(init=False)
    fragments: Fragments = field(init=False)
    said: list[Note] = field(init=False)  # what its bounds gave up (`capacity`), for the record being read
    record: int = 0  # the number of the record being read (the handshake messages' records are a key's origin)
    time: float | None = None  # and its time (fragments expire)

    def __post_init__(self) -> None:
        self.said = self.wpa.said if self.wpa is not None else []
        self.retries = Retries(said=self.said)
        self.relays = Relays(said=self.said)
        self.fragments = Fragments(said=self.said)
