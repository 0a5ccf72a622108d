"""TCP stream reassembly: per-direction, in sequence order, with retransmissions trimmed and holes noted.

A direction of a connection (a 4-tuple read one way) may hold several generations, each a stream of its
own: a SYN with a new initial sequence number (ISN) starts one. After a FIN or RST (or on a direction
that carried no data yet) that is a new connection reusing the 4-tuple. On an established direction it
is what an attacker injects to desynchronise a passive observer: a real endpoint ignores such a SYN
(RFC 5961 section 4: a challenge ACK, the connection unchanged). So the established generation is kept,
the SYN is noted (`tcp-suspicious-syn`), and every segment goes to the generation whose next expected
sequence number is nearest to its own: the established stream keeps every byte, and whatever follows
the new ISN (the SYN's own data, a real new connection whose FIN we missed) is a stream of its own.

Holes. Bytes after a missing range wait for it only while the capture may still hold it. The range is
given up, noted `tcp-gap` (its size, sequence numbers and why) on the bytes after it, as soon as:
- the peer acknowledges bytes of it: the receiver had them, the capture missed them (Wireshark's "ACKed
  segment that wasn't captured", TCP_A_ACK_LOST_PACKET in packet-tcp.c's tcp_analyze_sequence_number);
- the stream goes on without it (Wireshark's "previous segment not captured", TCP_A_LOST_PACKET): no
  segment fills it within HOLE_TIMEOUT of capture time after the bytes beyond it came (a retransmission
  after a lost segment comes in about a round trip, or after a retransmission timeout, at least 1 s by
  RFC 6298), or more than FAR_SEGMENTS segments or FAR_BYTES bytes came beyond it; a FIN or RST; the end
  of the capture; a memory bound below. Time is any record's, not only the stream's: the dissector ticks
  the reassembler (`tick`) with every record while a hole waits (`waiting`), so a hole among other
  traffic is given up on time, and after HOLE_RECORDS records whatever the clock says (a capture whose
  time stands still would hold it, and the records a later frame may be dated by, for ever).
The bytes after a hole are then read at once, each piece `ready` at the record where it became readable
in order (its own record, or the later one that filled the range before it), so a frame is dated by the
record that completed it, never by the moment reassembly gave up. Bytes that come after their range was
given up, or that lie before the first byte seen of a stream picked up mid-way, are delivered apart
(`stream` None, read as a datagram) with a `tcp-late` note: nothing a capture holds is hidden.

Memory is bounded whatever the input: out-of-order bytes per direction (`max_buffered`) and over all
directions (`max_total`, each buffered segment charged SEGMENT_COST for its bookkeeping), directions
tracked at once (`max_directions`, the least recently active released first), generations per direction
(GENERATIONS), holes remembered per direction (HOLES_KEPT), and a direction idle for `idle_records`
records is released. Buffered bytes given up to a bound are delivered after a `tcp-gap` note.
"""

from __future__ import annotations

import heapq
from collections import OrderedDict, deque
from collections.abc import Hashable

from mavscope.endpoint import Endpoint
from mavscope.notes import Note, note
from mavscope.transport.base import TRANSPORT_TCP, Payload
from mavscope.transport.tcp_direction import HALF, HOLES_KEPT, MOD, NEVER, Direction, Waits

TCP_FIN = 0x01
TCP_SYN = 0x02
TCP_RST = 0x04
TCP_ACK = 0x10
GAP = "tcp-gap"  # the note on the bytes after a hole: a stream framer starts afresh there
MAX_BUFFERED = 1 << 20  # out-of-order bytes held per direction before the missing range is given up
MAX_TOTAL_BUFFERED = 32 << 20  # ... and over all directions, counting SEGMENT_COST per buffered segment
SEGMENT_COST = 200  # bytes a buffered segment costs beyond its data (its tuple, bytes header, heap slot)
MAX_DIRECTIONS = 1 << 16  # directions (of any generation) tracked at once; about 0.5 KB each
GENERATIONS = 2  # generations kept per direction of a 4-tuple: the established one and a newer one
IDLE_RECORDS = 1_000_000  # a direction without a segment for this many records is released
ENDED_KEPT = 1 << 16  # ended stream keys kept for pop_ended() (older ones are forgotten)
PENDING_NOTES = 16  # suspicious-SYN notes held for a direction before they go out on an empty payload
HOLE_TIMEOUT = 2.0  # seconds of capture time a hole is waited for after the bytes beyond it came
FAR_SEGMENTS = 64  # segments beyond a hole that give it up ...
FAR_BYTES = 1 << 16  # ... or bytes beyond it (the largest window without window scaling, RFC 7323)
HOLE_RECORDS = 1 << 18  # records (of any kind) a hole is waited for after the bytes beyond it came, whatever the time

_tuple_new = tuple.__new__


class TcpReassembler:
    """Turns TCP segments into in-order stream Payloads, one reassembler per capture.

    A stream key is ("tcp", src, dst, generation); generations are numbered in the order directions are
    first seen, over the whole capture, so a key never names two streams. `pop_ended()` returns the keys
    of streams that ended (FIN, RST) or were released, so a consumer can let their state go. A stream
    Payload's `ready` is None when its bytes became readable in order in the record being read, else the
    (record, capture time) at which they did.
    """

    def __init__(self, max_buffered: int = MAX_BUFFERED, max_total: int = MAX_TOTAL_BUFFERED,
                 max_directions: int = MAX_DIRECTIONS, idle_records: int = IDLE_RECORDS) -> None:
        self.max_buffered = max_buffered
        self.max_total = max_total
        self.max_directions = max_directions
        self.idle_records = idle_records
        self.total = 0  # charged bytes buffered over all directions
        self.given_up = 0  # directions released to the bound on directions while their stream went on
        self.clock = -NEVER  # the latest capture time seen (a time that goes back does not move it)
        self.current: int | None = None  # the record being read (None at the end of the capture)
        self._slots: dict[tuple[Endpoint, Endpoint], list[Direction]] = {}  # (src, dst) -> generations, oldest first
        self._lru: OrderedDict[Hashable, Direction] = OrderedDict()  # every direction, least recently active first
        self._buffering: OrderedDict[Hashable, Direction] = OrderedDict()  # those holding bytes, oldest first
        self.waits = Waits()  # those waiting on a hole, by how long
        self._holes, self._due = self.waits.holes, self.waits.due  # (the same objects)
        self._notes: dict[tuple[Endpoint, Endpoint], list[Note]] = {}  # notes for the next payload of a (src, dst)
        self._serial = 0
        # keys of streams that ended (FIN, RST) or were released, oldest first, for a consumer to let their
        # state go (popleft; or pop_ended()); only the latest ENDED_KEPT are kept
        self.ended: deque[Hashable] = deque(maxlen=ENDED_KEPT)

    def segment(
        self, src: Endpoint, dst: Endpoint, seq: int, flags: int, data: bytes, record: int, offset: int | None,
        ack: int | None = None, time: float | None = None,
    ) -> list[Payload]:
        """Take one segment (payload `data` at file `offset`, acknowledgment number `ack`, in a record of
        capture time `time`) and return the bytes now in order (of its direction, and of the other one
        where `ack` gives up a hole)."""
        out: list[Payload] = []
        self.current = record
        if time is not None and time > self.clock:
            self.clock = time
        k = (src, dst)
        ds = self._slots.get(k)
        if flags & TCP_SYN:
            d = self._syn(k, ds, seq, flags, record, offset, len(data), out)
            seq = (seq + 1) % MOD
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
                d.ready, d.ready_time = record, time
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, src, dst, data, d.key, record, offset, (), None, None)))
            else:
                self._add(d, start, data, record, offset, time, out)
        if flags & (TCP_FIN | TCP_RST):
            self._close(d, seq, flags, len(data), out)
        if ack is not None and flags & TCP_ACK:
            peer = self._slots.get((dst, src))
            # (an ACK changes nothing unless it passes the bytes delivered: _ack; most do not)
            if peer is not None and (len(peer) > 1 or 0 < (ack - peer[0].next) % MOD < HALF):
                self._ack(peer, ack, record, out)
        if self._notes and k in self._notes:
            self._attach(k, out)
        if self.waits.any_due(self.clock, record, HOLE_TIMEOUT, HOLE_RECORDS):
            self._expire(out)
        if self.total > self.max_total or len(self._lru) > self.max_directions or \
                record - next(iter(self._lru.values())).last > self.idle_records:
            self._sweep(record, out)
        return out

    @property
    def waiting(self) -> bool:
        """Whether a hole is waited for: every record (of any kind) must then be `tick`ed."""
        return bool(self._holes)

    def tick(self, record: int, time: float | None) -> list[Payload]:
        """Record `record` (of capture time `time`) was read, whatever it carried: the holes it ends the
        wait for (HOLE_TIMEOUT, HOLE_RECORDS) are given up, and what they held back is returned."""
        out: list[Payload] = []
        self.current = record
        if time is not None and time > self.clock:
            self.clock = time
        if self.waits.any_due(self.clock, record, HOLE_TIMEOUT, HOLE_RECORDS):
            self._expire(out)
        return out

    @property
    def holding(self) -> bool:
        """Whether bytes are buffered out of order (a later record may date frames by an earlier one)."""
        return bool(self._buffering)

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
        """Deliver everything still buffered (end of capture), noting the holes skipped."""
        out: list[Payload] = []
        self.current = None
        for d in list(self._buffering.values()):
            self._drain(d, out, NEVER, "the capture ended without them")
        for d in list(self._holes.values()):  # bytes the receiver acknowledged, never captured
            if d.acked is not None and d.acked > d.next and not d.closed:
                why = f"the receiver acknowledged them (record {d.acked_by}): the capture missed them"
                out.append(self._empty(d, (self._gap(d, d.acked, why, None),)))
        for k in list(self._notes):
            ds = self._slots.get(k)
            key = ds[-1].key if ds else (TRANSPORT_TCP, k[0], k[1], -1)
            out.append(Payload(TRANSPORT_TCP, k[0], k[1], b"", key, self._notes_record(k), None,
                               tuple(self._notes.pop(k))))
        return out

    # --- generations --------------------------------------------------------------------------

    def _open(self, k: tuple[Endpoint, Endpoint], isn: int, nxt: int, syn: bool, record: int,
              out: list[Payload]) -> Direction:
        d = Direction(k[0], k[1], isn, nxt, self._serial, syn, record)
        self._serial += 1
        ds = self._slots.setdefault(k, [])
        ds.append(d)
        self._lru[d.key] = d
        if len(ds) > GENERATIONS:
            # give up the least useful: one that carried no data or has ended, else the least recently active
            idle = [g for g in ds[:-1] if not g.data or g.closed]
            self._release(idle[0] if idle else min(ds[:-1], key=lambda g: g.last), out, "",
                          "given up: a newer connection on its 4-tuple")
        return d

    def _syn(self, k: tuple[Endpoint, Endpoint], ds: list[Direction] | None, seq: int, flags: int, record: int,
             offset: int | None, size: int, out: list[Payload]) -> Direction:
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

    def _answers(self, k: tuple[Endpoint, Endpoint], live: list[Direction]) -> bool:
        """Whether a SYN-ACK on `k` answers a SYN the other way that is newer than `k`'s live generations."""
        newest = max(g.gen for g in live)
        return any(g.syn and not g.data and g.gen > newest for g in self._slots.get((k[1], k[0]), ()))

    def _close(self, d: Direction, seq: int, flags: int, size: int, out: list[Payload]) -> None:
        """A FIN or RST: what is buffered is delivered; with a plausible sequence number the stream ended
        (an RST ends the other direction too), and a FIN says where its bytes end."""
        how = "FIN" if flags & TCP_FIN else "RST"
        if d.pending:
            self._drain(d, out, NEVER, f"the stream ended ({how}) without them")
        if d.closed or d.distance((seq + size) % MOD) > max(self.max_buffered, 1 << 16):
            return
        end = d.unwrap((seq + size) % MOD)
        if flags & TCP_FIN and end > d.next:  # bytes before the FIN the capture does not hold
            out.append(self._empty(d, (self._gap(d, end, "the stream ended (FIN) without them", None),)))
        d.closed = True
        self.ended.append(d.key)
        if flags & TCP_RST:
            for g in self._slots.get((d.dst, d.src), ()):
                if not g.closed:
                    if g.pending:
                        self._drain(g, out, NEVER, "the connection was reset (RST) without them")
                    g.closed = True
                    self.ended.append(g.key)

    def _ack(self, ds: list[Direction], ack: int, record: int, out: list[Payload]) -> None:
        """An acknowledgment of the direction the other way (its generations `ds`): its receiver had every
        byte before `ack`, so a hole among them is one the capture missed, given up now (or when bytes beyond
        it come, or HOLE_TIMEOUT later). An ACK past what its sender can have sent unseen (more than
        `max_buffered` beyond the bytes seen: another connection's, or made up) is not taken."""
        g = ds[0] if len(ds) == 1 else min(ds, key=lambda g: g.distance(ack))
        a = g.unwrap(ack)
        if g.closed or a <= g.next or (g.acked is not None and a <= g.acked) or \
                a - max(g.next, g.high) > self.max_buffered:
            return
        g.acked, g.acked_by = a, record
        if g.pending:
            self._drain(g, out, a, "")
        else:
            self._wait(g)

    def _release(self, d: Direction, out: list[Payload], bound: str, reason: str) -> None:
        """Forget direction `d`, delivering what it buffered after a note saying `reason`; `bound` (if given),
        the bound it was released to, is noted when its stream went on."""
        if d.pending:
            self._drain(d, out, NEVER, reason)
        elif bound and d.data and not d.closed:
            self.given_up += 1
            if not self.given_up & (self.given_up - 1):  # the 1st, 2nd, 4th, 8th...: a flood is not noted one by one
                msg = (f"TCP stream {d.src} -> {d.dst}: reassembly state given up ({bound}; {self.given_up} so far); "
                       "what follows starts a new stream")
                out.append(Payload(TRANSPORT_TCP, d.src, d.dst, b"", d.key, d.last, None, (note(GAP, msg),)))
        del self._lru[d.key]
        self._holes.pop(d.key, None)
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
                bound = f"more than {self.max_directions} TCP directions at once"
                self._release(d, out, bound, f"given up: {bound}")
            elif record - d.last > self.idle_records:
                self._release(d, out, "", f"the stream was idle for {self.idle_records} records")
            else:
                break
        while self.total > self.max_total and self._buffering:
            d = next(iter(self._buffering.values()))
            self._drain(d, out, NEVER, f"given up: more than {self.max_total} bytes buffered over all TCP streams")

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

    def _add(self, d: Direction, start: int, data: bytes, record: int, offset: int | None, time: float | None,
             out: list[Payload]) -> None:
        """Deliver or buffer a segment that is not simply the next in order."""
        end = start + len(data)
        if start < d.next:
            upto = min(end, d.next)
            late = d.late(start, upto)
            if late:  # bytes never delivered: shown apart, the rest as a retransmission
                for lo, hi in late:
                    out.append(self._late(d, lo, hi, start, data, record, offset))
                if sum(hi - lo for lo, hi in late) < upto - start:
                    out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                                    (d.retransmitted(start, data[:upto - start], offset),), None,
                                                    None)))
                if end <= d.next:
                    return
                data, offset, start = data[upto - start:], None if offset is None else offset + upto - start, upto
                if not d.pending:
                    d.deliver(data)
                    d.ready, d.ready_time = record, time
                    out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, data, d.key, record, offset, (), None,
                                                    None)))
                    return
            elif end <= d.next:
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                                (d.retransmitted(start, data, offset),), None, None)))
                return
        d.counter += 1
        if not d.pending:
            self._buffering[d.key] = d
        heapq.heappush(d.pending, (start, d.counter, data, record, offset, time, self.clock))
        d.buffered += len(data)
        self.total += len(data) + SEGMENT_COST
        if end > d.high:
            d.high = end
        self._drain(d, out, d.acked if d.acked is not None else -NEVER, "")

    def _drain(self, d: Direction, out: list[Payload], upto: float, why: str) -> None:
        """Deliver the buffered segments now in order.

        A hole before stream position `upto` is given up for `why` (empty: the peer acknowledged it); one
        after it when the stream went on too far beyond it (_beyond).
        """
        pending = d.pending
        while pending:
            start, _, data, record, offset, time, _ = pending[0]
            notes: tuple[Note, ...] = ()
            if start > d.next:
                if d.next < upto:
                    stop = min(start, int(upto)) if upto < NEVER else start
                    reason = why or f"the receiver acknowledged them (record {d.acked_by}): the capture missed them"
                else:
                    stop, reason = start, self._beyond(d)
                    if not reason:
                        break
                notes = (self._gap(d, stop, reason, offset if stop == start else None),)
                if stop < start:  # the rest of the range is waited for
                    out.append(self._empty(d, notes))
                    continue
            heapq.heappop(pending)
            d.buffered -= len(data)
            self.total -= len(data) + SEGMENT_COST
            if not pending:
                del self._buffering[d.key]
            end = start + len(data)
            if end <= d.next:
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                                notes + (d.retransmitted(start, data, offset),), None, None)))
                continue
            if start < d.next:
                cut = d.next - start
                notes += (d.retransmitted(start, data, offset),)
                data = data[cut:]
                if offset is not None:
                    offset += cut
            d.deliver(data)
            if record > d.ready:  # readable in order from its own record (else from the one that filled a hole)
                d.ready, d.ready_time = record, time
            ready = None if d.ready == self.current else (d.ready, d.ready_time)
            out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, data, d.key, record, offset, notes, None,
                                            ready)))
        self._wait(d)

    def _beyond(self, d: Direction) -> str:
        """Why the hole at `next` is given up now that bytes beyond it came, if it is: a bound, or the stream
        went on too far without it ("" when it is waited for)."""
        if d.buffered > self.max_buffered:
            return f"given up: more than {self.max_buffered} bytes buffered beyond them"
        if len(d.pending) > FAR_SEGMENTS:
            return f"the capture missed them: {len(d.pending)} segments came beyond them"
        if d.high - d.next > FAR_BYTES:
            return f"the capture missed them: the stream went on {d.high - d.next} bytes beyond them"
        return ""

    def _wait(self, d: Direction) -> None:
        """Keep the waits (the directions waiting on a hole, for HOLE_TIMEOUT or HOLE_RECORDS) up to date with
        `d`: a hole with bytes beyond it (since the first segment beyond it came: the clock at its arrival,
        which a hole left when an earlier one was filled may have waited long already), or bytes its receiver
        acknowledged unseen (since the ACK). The oldest is given up first, whichever direction it is on and
        whenever it was found."""
        if d.pending or (d.acked is not None and d.acked > d.next and not d.closed):
            if d.since == NEVER or d.hole != d.next:  # a new hole
                self.waits.wait(d, d.pending[0][6] if d.pending else self.clock, self.current or 0)
        elif d.since != NEVER:
            self.waits.stop(d)

    def _expire(self, out: list[Payload]) -> None:
        """Give up the holes nothing filled for HOLE_TIMEOUT after the bytes beyond them came (or their ACK),
        or for HOLE_RECORDS records, the oldest first: the bytes after each are read."""
        while (due := self.waits.next_due(self.clock, self.current or 0, HOLE_TIMEOUT, HOLE_RECORDS)) is not None:
            d, waited = due  # (what is left, if any, is waited for anew: _wait, by _drain's or below)
            if d.pending:
                self._drain(d, out, d.pending[0][0], f"the capture missed them: {waited}")
                continue
            if d.hole == d.next and d.acked is not None and d.acked > d.next and not d.closed:
                why = f"the receiver acknowledged them (record {d.acked_by}): the capture missed them"
                out.append(self._empty(d, (self._gap(d, d.acked, why, None),)))
            self._wait(d)

    def _gap(self, d: Direction, stop: int, reason: str, offset: int | None) -> Note:
        """Skip the hole [next, stop): the note on the bytes after it, which a stream framer starts afresh at."""
        lo = d.next
        d.next, d.tail = stop, b""
        holes = d.holes if d.holes is not None else []
        holes.append((lo, stop))
        if len(holes) > HOLES_KEPT:  # the two oldest become one: bytes between them that come again are read
            holes[0:2] = [(holes[0][0], holes[1][1])]  # apart too (a second copy shown, never a frame hidden)
        d.holes = holes
        return note(GAP, f"{stop - lo} bytes missing from the TCP stream {d.src} -> {d.dst} ({d.span(lo, stop)}): "
                    f"{reason}", offset)

    def _empty(self, d: Direction, notes: tuple[Note, ...]) -> Payload:
        """A payload of no bytes carrying `notes`, at the record being read (else the direction's last)."""
        record = d.last if self.current is None else self.current
        return _tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, None, notes, None, None))

    def _late(self, d: Direction, lo: int, hi: int, start: int, data: bytes, record: int,
              offset: int | None) -> Payload:
        """Bytes [lo, hi) of a segment at `start` that were never delivered, shown apart from the stream."""
        at = None if offset is None else offset + lo - start
        msg = (f"{hi - lo} bytes of the TCP stream {d.src} -> {d.dst} ({d.span(lo, hi)}) came after the stream went "
               "on without them (a hole given up, or before its first byte seen): read apart from the stream")
        return _tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, data[lo - start:hi - start], None, record, at,
                                    (note("tcp-late", msg, at),), None, None))
