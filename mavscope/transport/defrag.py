"""IP fragment reassembly, by the rules of the receiving host's kernel (Linux's: the host of SITL,
companion computers, ground stations and of most captures).

A UDP datagram larger than the path's MTU arrives as IP fragments; the receiver's kernel puts them
back together and its MAVLink parser reads the whole datagram. A tool that reads packet by packet
shows the first fragment's bytes at most, and an attacker can send a command in fragments to hide
it. Wireshark reassembles, first fragment's bytes first; the receiver's kernel decides differently
where fragments disagree, and mavscope follows the kernel (net/ipv4/ip_fragment.c,
net/ipv6/reassembly.c, net/ipv4/inet_fragment.c):

- a datagram is (IP version, source, destination, protocol for IPv4, identification);
- a fragment that overlaps another partly discards the whole datagram (RFC 5722; Linux does the
  same for IPv4); one that lies inside a run of fragments already held is a duplicate and dropped:
  the first bytes are kept. Runs are the fragments that arrived in order at the datagram's end, so
  the same bytes can be a duplicate in one arrival order and an overlap in another;
- a last fragment that ends before bytes already held, a second last fragment with another end, a
  fragment past the last one's end and an empty fragment discard the datagram; a middle fragment
  whose length is not a multiple of 8 is cut to one (IPv4) or dropped (IPv6);
- a datagram longer than 65,535 bytes is discarded, so is one whose fragments mix ECN codepoints badly
  (Not-ECT with ECT or CE: RFC 3168 5.3), and so is a first IPv6 fragment that does not hold
  every header through the upper-layer one (RFC 8200 4.5: the tiny-fragment trick, which hides a UDP
  header from a filter that looks at first fragments);
- a datagram not complete 30 s (IPv4) or 60 s (IPv6) after its first fragment is discarded, and so
  is one whose source sent more than 64 other IPv4 fragments between two of its fragments
  (ipfrag_max_dist), counted from the first fragment that reached it, even one it dropped; while the
  fragments held pass 4 MiB (each counted with an overhead, as Linux
  counts its buffers: at most some 5,000 fragments are held) every fragment is dropped.

What the receiver drops is noted on the record that made it drop it (the registry's `ip-fragment*`
codes), naming the records of the fragments: nothing vanishes and nothing is read that the receiver
would not read.
"""

from __future__ import annotations

import socket
from bisect import bisect_right, insort
from dataclasses import dataclass, field
from typing import NamedTuple

from mavscope.notes import GivenUp, Note, note
from mavscope.transport.ip import MAX_EXT_HEADERS, PROTO_TCP, PROTO_UDP, FragmentInfo, walk_ipv6

TIMEOUT_V4 = 30.0  # net.ipv4.ipfrag_time
TIMEOUT_V6 = 60.0  # net.ipv6.ip6frag_time
MAX_DIST = 64  # net.ipv4.ipfrag_max_dist
MAX_HELD = 4 << 20  # net.ipv4.ipfrag_high_thresh, in bytes of buffer
FRAGMENT_COST = 768  # what a fragment costs besides its bytes (about a small sk_buff's truesize overhead)
QUEUE_COST = 256  # what a datagram's queue costs (Linux charges its inet_frag_queue when it makes one)
MAX_DATAGRAM = 65535
# the upper-layer header a first IPv6 fragment must hold (Linux's ipv6frag_thdr_truncated: TCP, UDP, ICMPv6;
# one byte of any other)
UPPER_HEADER = {PROTO_TCP: 20, PROTO_UDP: 8, 58: 8}
MAX_SOURCES = 65536  # sources whose IPv4 fragments are counted for MAX_DIST before the count starts over
RECORDS_NAMED = 8  # records a note names (the rest counted)
RECORDS_KEPT = 64  # records a datagram keeps for its notes (the rest counted)

Key = tuple[bool, bytes, bytes, int, int]  # (IPv6, source, destination, IPv4 protocol or 0, identification)


class Reassembled(NamedTuple):
    """A whole datagram: its fragmentable part (IPv4: the payload; IPv6: what follows the Fragment
    header), its protocol, and the records of its fragments."""

    data: bytes
    proto: int
    records: tuple[int, ...]  # in record order
    header_zero: bool = False  # one of its IPv4 fragments had a header checksum of 0 (not judged)


@dataclass(slots=True)
class _Datagram:
    key: Key
    proto: int
    start: float | None  # time of the first fragment (the receiver's timer starts there)
    dist: int = 0  # the source's IPv4 fragment count at this datagram's last fragment
    cost: int = QUEUE_COST  # what it and its fragments count against MAX_HELD
    ecn: int = 0  # its fragments' ECN codepoints, a bit each (Linux's IPFRAG_ECN_*: 1 << codepoint)
    header_zero: bool = False  # one of its IPv4 fragments had a header checksum of 0
    length: int = 0  # the datagram's length as far as known (Linux's q.len)
    last_in: bool = False
    first_in: bool = False
    meat: int = 0
    header_len: int = 0  # the first fragment's IP header (IPv4) or unfragmentable part (IPv6)
    runs: list[list[int]] = field(default_factory=list)  # [start, end]: disjoint, by start
    frags: list[tuple[int, bytes, int]] = field(default_factory=list)  # (offset, bytes, record), by offset
    records: list[int] = field(default_factory=list)  # its fragments' first RECORDS_KEPT records, in arrival order
    more_records: int = 0  # and how many more there were
    last_record: int = 0

    def took(self, record: int) -> None:
        """A fragment of this datagram came in `record`."""
        self.last_record = record
        if len(self.records) < RECORDS_KEPT:
            self.records.append(record)
        else:
            self.more_records += 1


def _start(frag: tuple[int, bytes, int]) -> int:
    return frag[0]


def _describe(d: _Datagram) -> str:
    v6, src, dst, _, ident = d.key
    fam = socket.AF_INET6 if v6 else socket.AF_INET
    return (f"IPv{6 if v6 else 4} datagram id {ident} from {socket.inet_ntop(fam, src)} to "
            f"{socket.inet_ntop(fam, dst)}")


def records_text(records: list[int] | tuple[int, ...], more_records: int = 0) -> str:
    """"records 1, 2, 3 and 5 more": the records of a datagram's fragments, for a note."""
    seen = sorted(set(records))
    more = len(seen) - RECORDS_NAMED + more_records
    text = ", ".join(map(str, seen[:RECORDS_NAMED]))
    return f"record{'s' if len(seen) > 1 else ''} {text}" + (f" and {more} more" if more > 0 else "")


class Defragmenter:
    """The fragments held for reassembly across the records of one capture."""

    def __init__(self, max_held: int = MAX_HELD, said: list[Note] | None = None) -> None:
        self.max_held = max_held
        self.given_up = GivenUp(f"IP reassembly's fragment counts (ipfrag_max_dist) for at most {MAX_SOURCES:,} "
                                "sources", "sources", said)
        self.held = 0  # what the datagrams held cost (QUEUE_COST each, their fragments' bytes, FRAGMENT_COST each)
        self.pending: dict[Key, _Datagram] = {}  # in the order they started
        self._dist: dict[bytes, int] = {}  # IPv4 fragments seen per source (ipfrag_max_dist)

    def add(self, frag: FragmentInfo, proto: int, src: bytes, dst: bytes, data: bytes, record: int,
            time: float | None, offset: int | None) -> tuple[Reassembled | None, list[Note]]:
        """Take one fragment (`data`: its bytes past the IP header, or the IPv6 Fragment header; `offset`:
        their file offset). Returns the datagram it completes, if any, and the notes of what the receiver
        dropped on the way, for this record."""
        notes: list[Note] = []
        if time is not None:
            self._expire(time, notes, offset)
        if self.held > self.max_held:
            notes.append(note("ip-fragment-dropped", f"{frag.describe()}: more than {self.max_held:,} bytes of "
                              "fragments are held for reassembly, so the receiver drops every fragment until its "
                              "timer discards some datagrams (Linux's ipfrag_high_thresh)", offset))
            return None, notes
        key: Key = (frag.v6, src, dst, 0 if frag.v6 else proto, frag.ident)
        d = self.pending.get(key)
        if len(data) < frag.length:  # a snapped record: the receiver had bytes the capture does not
            msg = (f"{frag.describe()}: the capture holds {len(data)} of its {frag.length} bytes, so its datagram "
                   "cannot be reassembled from the capture")
            if d is None:
                notes.append(note("ip-fragment", msg, offset))
            else:
                d.took(record)
                self._drop(d, notes, "ip-fragment", msg, offset)
            return None, notes
        if frag.v6 and frag.offset == 0 and self._truncated(proto, data):
            notes.append(note("ip-fragment-dropped", f"{frag.describe()}: a first fragment that does not hold its "
                              "headers through the upper-layer header (RFC 8200 4.5): the receiver drops it", offset))
            return None, notes
        dist = 0
        if not frag.v6:
            if src not in self._dist and len(self._dist) >= MAX_SOURCES:
                self.given_up.add("the counts start over, so a datagram a receiver drops for ipfrag_max_dist may be "
                                  "reassembled and shown", len(self._dist))
                self._dist.clear()
            dist = self._dist[src] = self._dist.get(src, 0) + 1
        if d is not None and not frag.v6 and dist - d.dist > MAX_DIST:
            self._drop(d, notes, "ip-fragment-dropped", f"its source sent {dist - d.dist - 1} other IPv4 "
                       f"fragments between two of its fragments (Linux's ipfrag_max_dist, {MAX_DIST}): the "
                       "receiver starts it over at this fragment", offset)
            d = None
        if d is None:  # (the receiver makes the queue, and starts its timer, before it looks at the fragment)
            d = self.pending[key] = _Datagram(key, proto, time)
            self.held += QUEUE_COST
        d.dist = dist
        d.took(record)
        return self._insert(d, frag, proto, data, record, notes, offset), notes

    @staticmethod
    def _truncated(proto: int, data: bytes) -> bool:
        """Whether a first IPv6 fragment (`data`: after its Fragment header) stops before the end of its
        upper-layer header."""
        p = 0
        for _ in range(MAX_EXT_HEADERS):
            walked = walk_ipv6(data, p, len(data), proto)
            if isinstance(walked, str):
                return True
            proto, p, inner = walked
            if inner is None:
                return p + UPPER_HEADER.get(proto, 1) > len(data)
            if inner.offset:  # ipv6_skip_exthdr stops at a Fragment header with an offset: not checked
                return False
        return True

    def flush(self) -> list[tuple[int, Note]]:
        """End of capture: (record, note) for each datagram never completed, at its last fragment's record."""
        out = [(d.last_record, self._incomplete(d, "the capture ends before it is complete", None))
               for d in self.pending.values() if d.frags]  # (one holding none: each fragment was noted)
        self.pending.clear()
        self.held = 0
        return out

    # --- one datagram ---------------------------------------------------------------------------------

    def _insert(self, d: _Datagram, frag: FragmentInfo, proto: int, data: bytes, record: int,
                notes: list[Note], offset: int | None) -> Reassembled | None:
        start = frag.offset
        end = start + len(data)
        what = f"{frag.describe()} (bytes {start}-{end})"
        if frag.v6 and end > MAX_DATAGRAM:
            notes.append(note("ip-fragment-dropped", f"{what} ends past byte {MAX_DATAGRAM}: the receiver drops "
                              "it", offset))
            return None
        if not frag.more:
            if end < d.length or (d.last_in and end != d.length):
                self._drop(d, notes, "ip-fragment-dropped", f"{what} is a last fragment ending at {end} "
                           f"where {'the last one ended' if d.last_in else 'bytes were held'} at {d.length}: "
                           "the receiver discards the datagram", offset)
                return None
            d.last_in, d.length = True, end
        else:
            if end & 7:
                if frag.v6:
                    notes.append(note("ip-fragment-dropped", f"{what}: a middle fragment whose length is not a "
                                      "multiple of 8; the receiver drops it", offset))
                    return None
                end &= ~7  # IPv4: cut to a multiple of 8
                data = data[:end - start]
            if end > d.length:
                if d.last_in:
                    self._drop(d, notes, "ip-fragment-dropped", f"{what} goes past the end the last "
                               f"fragment gave ({d.length}): the receiver discards the datagram", offset)
                    return None
                d.length = end
        if end == start:
            self._drop(d, notes, "ip-fragment-dropped", f"{what} is empty: the receiver discards the "
                       "datagram", offset)
            return None
        placed = self._place(d, start, end)
        if placed is not None:
            if placed == "overlap":
                self._drop(d, notes, "ip-fragment-overlap", f"{what} overlaps a fragment held: Linux "
                           "discards the whole datagram (RFC 5722); other IP stacks may reassemble it with "
                           "either fragment's bytes", offset)
                return None
            same = self._bytes_at(d, start, end) == data
            notes.append(note("ip-fragment-duplicate" if same else "ip-fragment-conflict",
                              f"{what} repeats bytes already held" + ("" if same else " with other bytes: the "
                              "receiver keeps the first and drops this one"), offset))
            return None
        insort(d.frags, (start, data, record), key=_start)
        d.ecn |= 1 << frag.ecn
        d.header_zero |= frag.header_zero
        d.meat += end - start
        d.cost += end - start + FRAGMENT_COST
        self.held += end - start + FRAGMENT_COST
        if start == 0:
            d.first_in, d.proto, d.header_len = True, proto, frag.header_len
        if not (d.first_in and d.last_in and d.meat == d.length):
            return None
        del self.pending[d.key]
        self.held -= d.cost
        if d.header_len + d.length > MAX_DATAGRAM:
            notes.append(self._incomplete(d, f"it is {d.header_len + d.length} bytes long, over {MAX_DATAGRAM}: "
                                          "the receiver discards it", offset, "ip-fragment-dropped"))
            return None
        if d.ecn & 1 and d.ecn != 1:  # Not-ECT beside ECT(0), ECT(1) or CE: ip_frag_ecn_table's 0xff
            notes.append(self._incomplete(d, "its fragments mix ECN codepoints (Not-ECT with ECT or CE): the "
                                          "receiver discards it (RFC 3168 5.3)", offset, "ip-fragment-dropped"))
            return None
        records = tuple(sorted({r for _, _, r in d.frags}))
        return Reassembled(b"".join(b for _, b, _ in d.frags), d.proto, records, d.header_zero)

    @staticmethod
    def _place(d: _Datagram, start: int, end: int) -> str | None:
        """Put [start, end) among the datagram's runs as Linux's inet_frag_queue_insert does: None when
        placed, "duplicate" when it lies inside one run, "overlap" when it overlaps partly."""
        runs = d.runs
        if not runs:
            runs.append([start, end])
            return None
        tail = runs[-1][1]
        if tail < end:  # at the datagram's end so far: the common case
            if start < tail:
                return "overlap"
            if start == tail:
                runs[-1][1] = end
            else:
                runs.append([start, end])
            return None
        i = bisect_right(runs, [start, end]) - 1  # the run starting at or before `start`, if any
        for j in (i, i + 1):
            if 0 <= j < len(runs) and runs[j][0] < end and start < runs[j][1]:
                return "duplicate" if runs[j][0] <= start and end <= runs[j][1] else "overlap"
        runs.insert(i + 1, [start, end])
        return None

    @staticmethod
    def _bytes_at(d: _Datagram, start: int, end: int) -> bytes:
        """The bytes held at [start, end) (inside one run: the fragments held cover it)."""
        frags = d.frags
        i = max(bisect_right(frags, start, key=_start) - 1, 0)  # the last fragment starting at or before it
        out = bytearray()
        while i < len(frags) and frags[i][0] < end:
            s, b, _ = frags[i]
            lo, hi = max(s, start), min(s + len(b), end)
            if lo < hi:
                out += b[lo - s:hi - s]
            i += 1
        return bytes(out)

    def _drop(self, d: _Datagram, notes: list[Note], code: str, why: str, offset: int | None) -> None:
        self.pending.pop(d.key, None)
        self.held -= d.cost
        notes.append(self._incomplete(d, why, offset, code))

    @staticmethod
    def _incomplete(d: _Datagram, why: str, offset: int | None, code: str = "ip-fragment") -> Note:
        have = f"{d.meat} of {'' if d.last_in and d.first_in else 'at least '}{d.length} bytes"
        return note(code, f"{_describe(d)}, fragments in {records_text(d.records, d.more_records)} ({have}): {why}",
                    offset)

    def _expire(self, now: float, notes: list[Note], offset: int | None) -> None:
        """Discard the datagrams the receiver's timer has discarded by `now` (oldest first)."""
        while self.pending:
            d = next(iter(self.pending.values()))
            timeout = TIMEOUT_V6 if d.key[0] else TIMEOUT_V4
            if d.start is None or now - d.start <= timeout:
                return
            if d.frags:
                self._drop(d, notes, "ip-fragment", f"not complete {timeout:.0f} s after its first fragment: "
                           "the receiver discards it", None)
            else:  # its fragments were all dropped, each with its note
                del self.pending[d.key]
                self.held -= d.cost
