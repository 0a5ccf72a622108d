"""TCP stream reassembly: per-direction, in sequence order, with retransmissions trimmed and gaps noted.

A direction of a connection (a 4-tuple read one way) may hold several generations, each a stream of its
own: a SYN with a new initial sequence number (ISN) starts one. After a FIN or RST (or on a direction
that carried no data yet) that is a new connection reusing the 4-tuple. On an established direction it
is what an attacker injects to desynchronise a passive observer: a real endpoint ignores such a SYN
(RFC 5961 section 4: a challenge ACK, the connection unchanged). So the established generation is kept,
the SYN is noted (`tcp-suspicious-syn`), and every segment goes to the generation whose next expected
sequence number is nearest to its own: the established stream keeps every byte, and whatever follows
the new ISN (the SYN's own data, a real new connection whose FIN we missed) is a stream of its own.

Memory is bounded whatever the input: out-of-order bytes per direction (`max_buffered`) and over all
directions (`max_total`, each buffered segment charged SEGMENT_COST for its bookkeeping), directions
tracked at once (`max_directions`, the least recently active released first), generations per direction
(GENERATIONS), and a direction idle for `idle_records` records is released. Buffered bytes given up to
a bound are delivered after a `tcp-gap` note, as at the end of a stream.
"""

from __future__ import annotations

import heapq
from collections import OrderedDict, deque
from collections.abc import Hashable

from mavscope.endpoint import Endpoint
from mavscope.notes import Note, note
from mavscope.transport.base import TRANSPORT_TCP, Payload

TCP_FIN = 0x01
TCP_SYN = 0x02
TCP_RST = 0x04
TCP_ACK = 0x10
MAX_BUFFERED = 1 << 20  # out-of-order bytes held per direction before the missing range is given up
MAX_TOTAL_BUFFERED = 32 << 20  # ... and over all directions, counting SEGMENT_COST per buffered segment
SEGMENT_COST = 200  # bytes a buffered segment costs beyond its data (its tuple, bytes header, heap slot)
MAX_DIRECTIONS = 1 << 16  # directions (of any generation) tracked at once; about 0.5 KB each
TAIL = 512  # bytes last delivered per direction that a retransmission is compared with (tcp-conflict)
GENERATIONS = 2  # generations kept per direction of a 4-tuple: the established one and a newer one
IDLE_RECORDS = 1_000_000  # a direction without a segment for this many records is released
ENDED_KEPT = 1 << 16  # ended stream keys kept for pop_ended() (older ones are forgotten)
PENDING_NOTES = 16  # suspicious-SYN notes held for a direction before they go out on an empty payload
_MOD = 1 << 32
_HALF = 1 << 31

_tuple_new = tuple.__new__


class _Direction:
    """Reassembly state of one generation of one direction of one connection."""

    __slots__ = ("src", "dst", "isn", "next", "gen", "key", "pending", "buffered", "counter", "syn", "data",
                 "closed", "last", "tail")

    def __init__(self, src: Endpoint, dst: Endpoint, isn: int, nxt: int, gen: int, syn: bool, record: int) -> None:
        self.src = src
        self.dst = dst
        self.isn = isn
        self.next = nxt  # next expected sequence number, unwrapped (a Python int that never wraps)
        self.gen = gen
        self.key: Hashable = (TRANSPORT_TCP, src, dst, gen)
        # out-of-order segments: (unwrapped seq, arrival counter, data, record, file offset)
        self.pending: list[tuple[int, int, bytes, int, int | None]] = []
        self.buffered = 0
        self.counter = 0
        self.syn = syn  # started by a SYN (so `isn` is an initial sequence number)
        self.data = False  # carried data: established
        self.closed = False  # a FIN or RST with a plausible sequence number was seen
        self.last = record  # the record of its latest segment
        self.tail = b""  # the last TAIL bytes delivered: stream positions [next - len(tail), next)

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
        return self.next + (((seq - self.next) + _HALF) % _MOD - _HALF)

    def distance(self, seq: int) -> int:
        """How far 32-bit sequence number `seq` lies from the next expected one, either way."""
        return abs(((seq - self.next) + _HALF) % _MOD - _HALF)


class TcpReassembler:
    """Turns TCP segments into in-order stream Payloads, one reassembler per capture.

    A stream key is ("tcp", src, dst, generation); generations are numbered in the order directions are
    first seen, over the whole capture, so a key never names two streams. `pop_ended()` returns the keys
    of streams that ended (FIN, RST) or were released, so a consumer can let their state go.
    """

    def __init__(self, max_buffered: int = MAX_BUFFERED, max_total: int = MAX_TOTAL_BUFFERED,
                 max_directions: int = MAX_DIRECTIONS, idle_records: int = IDLE_RECORDS) -> None:
        self.max_buffered = max_buffered
        self.max_total = max_total
        self.max_directions = max_directions
        self.idle_records = idle_records
        self.total = 0  # charged bytes buffered over all directions
        self.given_up = 0  # directions released to the bound on directions while their stream went on
        self._slots: dict[tuple[Endpoint, Endpoint], list[_Direction]] = {}  # (src, dst) -> generations, oldest first
        self._lru: OrderedDict[Hashable, _Direction] = OrderedDict()  # every direction, least recently active first
        self._buffering: OrderedDict[Hashable, _Direction] = OrderedDict()  # those holding bytes, oldest first
        self._notes: dict[tuple[Endpoint, Endpoint], list[Note]] = {}  # notes for the next payload of a (src, dst)
        self._serial = 0
        # keys of streams that ended (FIN, RST) or were released, oldest first, for a consumer to let their
        # state go (popleft; or pop_ended()); only the latest ENDED_KEPT are kept
        self.ended: deque[Hashable] = deque(maxlen=ENDED_KEPT)

    def segment(
        self, src: Endpoint, dst: Endpoint, seq: int, flags: int, data: bytes, record: int, offset: int | None
    ) -> list[Payload]:
        """Take one segment (payload `data` at file `offset`) and return the bytes now in order."""
        out: list[Payload] = []
        k = (src, dst)
        ds = self._slots.get(k)
        if flags & TCP_SYN:
            d = self._syn(k, ds, seq, flags, record, offset, len(data), out)
            seq = (seq + 1) % _MOD
        elif ds is None:
            d = self._open(k, seq, seq, False, record, out)
        elif len(ds) == 1:
            d = ds[0]
        else:  # the generation this segment continues
            d = min(ds, key=lambda g: g.distance(seq))
        if d.last != record:
            d.last = record
            self._lru.move_to_end(d.key)
        if data:
            d.data = True
            start = d.unwrap(seq)
            if start == d.next and not d.pending:  # the common case: the next bytes, nothing buffered
                d.deliver(data)
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, src, dst, data, d.key, record, offset, (), None)))
            else:
                self._add(d, start, data, record, offset, out)
        if flags & (TCP_FIN | TCP_RST):
            self._close(d, seq, flags, len(data), out)
        if k in self._notes:
            self._attach(k, out)
        if self.total > self.max_total or len(self._lru) > self.max_directions or \
                record - next(iter(self._lru.values())).last > self.idle_records:
            self._sweep(record, out)
        return out

    def tracked(self) -> int:
        """How many directions (of any generation) are tracked now."""
        return len(self._lru)

    def buffered_segments(self) -> int:
        """How many out-of-order segments are buffered now, over all directions."""
        return sum(len(d.pending) for d in self._buffering.values())

    def pop_ended(self) -> list[Hashable]:
        """Keys of the streams that ended or were released since the last call (the latest ENDED_KEPT)."""
        ended = list(self.ended)
        self.ended.clear()
        return ended

    def flush(self) -> list[Payload]:
        """Deliver everything still buffered (end of capture), noting the gaps skipped."""
        out: list[Payload] = []
        for d in list(self._buffering.values()):
            self._drain(d, out, gaps=True)
        for k in list(self._notes):
            ds = self._slots.get(k)
            key = ds[-1].key if ds else (TRANSPORT_TCP, k[0], k[1], -1)
            out.append(Payload(TRANSPORT_TCP, k[0], k[1], b"", key, self._notes_record(k), None,
                               tuple(self._notes.pop(k))))
        return out

    # --- generations --------------------------------------------------------------------------

    def _open(self, k: tuple[Endpoint, Endpoint], isn: int, nxt: int, syn: bool, record: int,
              out: list[Payload]) -> _Direction:
        d = _Direction(k[0], k[1], isn, nxt, self._serial, syn, record)
        self._serial += 1
        ds = self._slots.setdefault(k, [])
        ds.append(d)
        self._lru[d.key] = d
        if len(ds) > GENERATIONS:
            # give up the least useful: one that carried no data or has ended, else the least recently active
            idle = [g for g in ds[:-1] if not g.data or g.closed]
            self._release(idle[0] if idle else min(ds[:-1], key=lambda g: g.last), out, "")
        return d

    def _syn(self, k: tuple[Endpoint, Endpoint], ds: list[_Direction] | None, seq: int, flags: int, record: int,
             offset: int | None, size: int, out: list[Payload]) -> _Direction:
        """The generation a SYN belongs to: its own if retransmitted, else a new one (noted if suspicious)."""
        if ds:
            for g in ds:
                if g.isn == seq:
                    return g  # a retransmitted SYN
        live = [g for g in ds or () if g.data and not g.closed and record - g.last <= self.idle_records]
        if live and not (flags & TCP_ACK and self._answers(k, live)):
            g = live[-1]
            data = f", its {size} data bytes shown as a stream of their own" if size else ""
            msg = (f"SYN with a new initial sequence number {seq} in the established TCP stream {g.src} -> {g.dst} "
                   f"(record {record}): a receiver ignores it (RFC 5961), so the stream goes on{data}")
            pending = self._notes.setdefault(k, [])
            pending.append(note("tcp-suspicious-syn", msg, offset))
        return self._open(k, seq, seq + 1, True, record, out)

    def _answers(self, k: tuple[Endpoint, Endpoint], live: list[_Direction]) -> bool:
        """Whether a SYN-ACK on `k` answers a SYN the other way that is newer than `k`'s live generations."""
        newest = max(g.gen for g in live)
        return any(g.syn and not g.data and g.gen > newest for g in self._slots.get((k[1], k[0]), ()))

    def _close(self, d: _Direction, seq: int, flags: int, size: int, out: list[Payload]) -> None:
        """A FIN or RST: what is buffered is delivered; with a plausible sequence number the stream ended
        (an RST ends the other direction too)."""
        if d.pending:
            self._drain(d, out, gaps=True)
        if d.closed or d.distance((seq + size) % _MOD) > max(self.max_buffered, 1 << 16):
            return
        d.closed = True
        self.ended.append(d.key)
        if flags & TCP_RST:
            for g in self._slots.get((d.dst, d.src), ()):
                if not g.closed:
                    if g.pending:
                        self._drain(g, out, gaps=True)
                    g.closed = True
                    self.ended.append(g.key)

    def _release(self, d: _Direction, out: list[Payload], why: str) -> None:
        """Forget direction `d`, delivering what it buffered; `why` (if given) is noted when it had data."""
        if d.pending:
            self._drain(d, out, gaps=True, why=why)
        elif why and d.data and not d.closed:
            self.given_up += 1
            if not self.given_up & (self.given_up - 1):  # the 1st, 2nd, 4th, 8th...: a flood is not noted one by one
                msg = (f"TCP stream {d.src} -> {d.dst}: reassembly state given up ({why}; {self.given_up} so far); "
                       "what follows starts a new stream")
                out.append(Payload(TRANSPORT_TCP, d.src, d.dst, b"", d.key, d.last, None, (note("tcp-gap", msg),)))
        del self._lru[d.key]
        k = (d.src, d.dst)
        ds = self._slots[k]
        ds.remove(d)
        if not ds:
            del self._slots[k]
            if k in self._notes:
                out.append(Payload(TRANSPORT_TCP, d.src, d.dst, b"", d.key, self._notes_record(k), None,
                                   tuple(self._notes.pop(k))))
        if not d.closed:
            self.ended.append(d.key)

    def _sweep(self, record: int, out: list[Payload]) -> None:
        """Keep within the bounds: directions tracked, idle directions, bytes buffered overall."""
        lru = self._lru
        while len(lru) > 1:
            d = next(iter(lru.values()))
            if len(lru) > self.max_directions:
                self._release(d, out, f"more than {self.max_directions} TCP directions at once")
            elif record - d.last > self.idle_records:
                self._release(d, out, "")
            else:
                break
        while self.total > self.max_total and self._buffering:
            d = next(iter(self._buffering.values()))
            self._drain(d, out, gaps=True, why=f"more than {self.max_total} bytes buffered over all TCP streams")

    def _attach(self, k: tuple[Endpoint, Endpoint], out: list[Payload]) -> None:
        """Put the notes waiting for `k` on its first payload in `out` (or on an empty one, when many wait)."""
        for i, p in enumerate(out):
            if p.src == k[0] and p.dst == k[1]:
                out[i] = p._replace(notes=tuple(self._notes.pop(k)) + p.notes)
                return
        if len(self._notes[k]) >= PENDING_NOTES:
            ds = self._slots[k]
            out.append(Payload(TRANSPORT_TCP, k[0], k[1], b"", ds[-1].key, self._notes_record(k), None,
                               tuple(self._notes.pop(k))))

    def _notes_record(self, k: tuple[Endpoint, Endpoint]) -> int:
        ds = self._slots.get(k)
        return max(g.last for g in ds) if ds else 0

    # --- bytes ----------------------------------------------------------------------------------

    def _add(
        self, d: _Direction, start: int, data: bytes, record: int, offset: int | None, out: list[Payload]
    ) -> None:
        """Deliver or buffer a segment that is not simply the next in order."""
        end = start + len(data)
        if end <= d.next:
            out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                            (d.retransmitted(start, data, offset),), None)))
            return
        d.counter += 1
        if not d.pending:
            self._buffering[d.key] = d
        heapq.heappush(d.pending, (start, d.counter, data, record, offset))
        d.buffered += len(data)
        self.total += len(data) + SEGMENT_COST
        self._drain(d, out, gaps=False)

    def _drain(self, d: _Direction, out: list[Payload], gaps: bool, why: str = "") -> None:
        """Deliver buffered segments that are now in order.

        Missing ranges are skipped (with a tcp-gap note) when `gaps` is set, or while the buffer is over
        its bound. `why` says which bound forced the gap, if one did.
        """
        pending = d.pending
        while pending:
            start, _, data, record, offset = pending[0]
            notes: tuple[Note, ...] = ()
            if start > d.next:
                if not gaps and d.buffered <= self.max_buffered:
                    return
                missing = start - d.next
                because = f" (given up: {why})" if why else ""
                notes = (note("tcp-gap", f"{missing} bytes missing from the TCP stream {d.src} -> {d.dst}{because}",
                              offset),)
                d.next, d.tail = start, b""
            heapq.heappop(pending)
            d.buffered -= len(data)
            self.total -= len(data) + SEGMENT_COST
            if not pending:
                del self._buffering[d.key]
            end = start + len(data)
            if end <= d.next:
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                                notes + (d.retransmitted(start, data, offset),), None)))
                continue
            if start < d.next:
                cut = d.next - start
                notes += (d.retransmitted(start, data, offset),)
                data = data[cut:]
                if offset is not None:
                    offset += cut
            d.deliver(data)
            out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, data, d.key, record, offset, notes, None)))
