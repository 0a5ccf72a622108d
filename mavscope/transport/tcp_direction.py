"""The reassembly state of one generation of one direction of a TCP connection (mavscope.transport.tcp)."""

from __future__ import annotations

import heapq
from collections import deque
from collections.abc import Hashable

from mavscope.endpoint import Endpoint
from mavscope.notes import Note, note
from mavscope.transport.base import TRANSPORT_TCP

TAIL = 512  # bytes last delivered per direction that a retransmission is compared with (tcp-conflict)
HOLES_KEPT = 64  # holes given up remembered per direction, for the bytes that come late (then merged)
MOD = 1 << 32
HALF = 1 << 31
NEVER = float("inf")

# a buffered segment: (unwrapped seq, arrival counter, data, record, file offset, capture time, clock at arrival)
Segment = tuple[int, int, bytes, int, int | None, float | None, float]


class Direction:
    """Reassembly state of one generation of one direction of one connection."""

    __slots__ = ("src", "dst", "isn", "next", "gen", "key", "pending", "buffered", "counter", "syn", "data",
                 "closed", "last", "tail", "base", "acked", "acked_by", "ready", "ready_time", "high", "hole",
                 "since", "holes", "forgot")

    def __init__(self, src: Endpoint, dst: Endpoint, isn: int, nxt: int, gen: int, syn: bool, record: int) -> None:
        self.src = src
        self.dst = dst
        self.isn = isn
        self.next = nxt  # next expected sequence number, unwrapped (a Python int that never wraps)
        self.gen = gen
        self.key: Hashable = (TRANSPORT_TCP, src, dst, gen)
        self.pending: list[Segment] = []  # out-of-order segments, a heap
        self.buffered = 0
        self.counter = 0
        self.syn = syn  # started by a SYN (so `isn` is an initial sequence number)
        self.data = False  # carried data: established
        self.closed = False  # a FIN or RST with a plausible sequence number was seen
        self.last = record  # the record of its latest segment
        self.tail = b""  # the last TAIL bytes delivered: stream positions [next - len(tail), next)
        self.base = isn if syn else nxt - 1  # relative sequence numbers count from here (Wireshark's: 1 first)
        self.acked: int | None = None  # the highest position the peer acknowledged ...
        self.acked_by = 0  # ... in this record
        self.ready = record  # the record at which the last byte delivered became readable in order ...
        self.ready_time: float | None = None  # ... and its capture time
        self.high = nxt  # the end of the highest segment seen
        self.hole = nxt  # the position of the hole waited for ...
        self.since = NEVER  # ... and the clock at which the bytes beyond it came (NEVER: no hole waited for)
        self.holes: list[tuple[int, int]] | None = None  # ranges given up, the latest HOLES_KEPT
        # bytes before this position were never delivered: a stream picked up mid-way (no SYN seen) starts
        # at its first byte seen
        self.forgot: int | None = None if syn else nxt

    def deliver(self, data: bytes) -> None:
        """`data` goes out in order after the bytes delivered so far."""
        self.next += len(data)
        self.tail = data[-TAIL:] if len(data) >= TAIL else (self.tail + data)[-TAIL:]

    def retransmitted(self, start: int, data: bytes, offset: int | None) -> Note:
        """The note on bytes at `start` that were delivered already: a conflict when they differ from what
        was delivered there (the part still in `tail` is compared), a chat note when they do not."""
        base = self.next - len(self.tail)  # the stream position of tail[0]
        n = min(start + len(data), self.next) - start  # the bytes delivered already
        lo = max(start, base)
        hi = max(lo, start + n)  # [lo, hi): those still in the tail
        old, new = self.tail[lo - base:hi - base], data[lo - start:hi - start]
        if old != new:
            at = next(i for i in range(len(old)) if old[i] != new[i])
            return note("tcp-conflict", f"TCP retransmission of {n} bytes already delivered, with other bytes (from "
                        f"its byte {lo - start + at}): the receiver keeps what it read first; a reader that takes "
                        "the retransmission sees other bytes", offset)
        older = n - (hi - lo)
        unchecked = f", {older} of them older than the last {TAIL} delivered (unchecked)" if older else ""
        return note("tcp-retransmission", f"TCP retransmission of {n} bytes already delivered{unchecked}", offset)

    def unwrap(self, seq: int) -> int:
        """The unwrapped position of 32-bit sequence number `seq`, taken as the one nearest `next`."""
        return self.next + (((seq - self.next) + HALF) % MOD - HALF)

    def distance(self, seq: int) -> int:
        """How far 32-bit sequence number `seq` lies from the next expected one, either way."""
        return abs(((seq - self.next) + HALF) % MOD - HALF)

    def span(self, lo: int, hi: int) -> str:
        """Stream positions [lo, hi) as sequence numbers, raw and relative (as Wireshark shows them)."""
        return f"sequence numbers {lo % MOD}-{(hi - 1) % MOD}, relative {lo - self.base}-{hi - 1 - self.base}"

    def late(self, lo: int, hi: int) -> list[tuple[int, int]]:
        """The parts of positions [lo, hi), all before `next`, that were never delivered: in the holes given up
        that are remembered, or before `forgot`."""
        ranges = sorted([*(() if self.forgot is None else ((lo, self.forgot),)), *(self.holes or ())])
        parts: list[tuple[int, int]] = []
        for a, b in ranges:
            a, b = max(a, lo), min(b, hi)
            if parts and a <= parts[-1][1]:
                if b > parts[-1][1]:
                    parts[-1] = (parts[-1][0], b)
            elif a < b:
                parts.append((a, b))
        return parts


class Waits:
    """The directions waiting on a hole (`since` not NEVER), found by how long they have waited: a heap of
    (since, serial, key) for the capture time, a queue of (record then, key, since) for the records; stale
    entries (a hole filled, given up or moved on since) are dropped as they surface or when most are."""

    __slots__ = ("holes", "due", "records", "_serial")

    def __init__(self) -> None:
        self.holes: dict[Hashable, Direction] = {}
        self.due: list[tuple[float, int, Hashable]] = []
        self.records: deque[tuple[int, Hashable, float]] = deque()
        self._serial = 0

    def wait(self, d: Direction, since: float, record: int) -> None:
        """`d` waits on the hole at its `next` since clock `since` (the bytes beyond it came in `record`)."""
        if since != d.since:  # (an entry with this `since` serves it already, else)
            self._serial += 1
            heapq.heappush(self.due, (since, self._serial, d.key))
            self.records.append((record, d.key, since))
        d.hole, d.since = d.next, since
        self.holes[d.key] = d
        if len(self.due) > 2 * len(self.holes) + 64:  # mostly stale: keep only the live entries
            self.due[:] = [e for e in self.due if self._live(e[2], e[0])]
            heapq.heapify(self.due)
            self.records = deque(e for e in self.records if self._live(e[1], e[2]))

    def stop(self, d: Direction) -> None:
        d.since = NEVER
        self.holes.pop(d.key, None)

    def _live(self, key: Hashable, since: float) -> bool:
        d = self.holes.get(key)
        return d is not None and d.since == since

    def any_due(self, clock: float, record: int, timeout: float, records: int) -> bool:
        return bool(self.due) and (clock - self.due[0][0] > timeout or record - self.records[0][0] > records)

    def next_due(self, clock: float, record: int, timeout: float, records: int) -> tuple[Direction, str] | None:
        """The next direction to give up (no longer waiting), and for how long it waited; None when none."""
        due, queue = self.due, self.records
        while due and not self._live(due[0][2], due[0][0]):
            heapq.heappop(due)
        if due and clock - due[0][0] > timeout:
            since, _, key = heapq.heappop(due)
            d = self.holes[key]
            self.stop(d)
            return d, f"nothing filled them in {clock - since:.3g} s after the bytes beyond them came"
        while queue and not self._live(queue[0][1], queue[0][2]):
            queue.popleft()
        if queue and record - queue[0][0] > records:
            d = self.holes[queue.popleft()[1]]
            self.stop(d)
            return d, f"nothing filled them in {records:,} records after the bytes beyond them came"
        return None
