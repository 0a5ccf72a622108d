"""TCP stream reassembly: per-direction, in sequence order, with retransmissions trimmed and gaps noted."""

from __future__ import annotations

import heapq
from collections.abc import Hashable

from mavscope.endpoint import Endpoint
from mavscope.notes import Note, note
from mavscope.transport.base import TRANSPORT_TCP, Payload

TCP_FIN = 0x01
TCP_SYN = 0x02
TCP_RST = 0x04
MAX_BUFFERED = 1 << 20  # out-of-order bytes held per direction before the missing range is given up
_MOD = 1 << 32
_HALF = 1 << 31

_tuple_new = tuple.__new__


class _Direction:
    """Reassembly state of one direction of one connection."""

    __slots__ = ("src", "dst", "isn", "next", "gen", "key", "pending", "buffered", "counter")

    def __init__(self, src: Endpoint, dst: Endpoint, isn: int, nxt: int, gen: int) -> None:
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

    def unwrap(self, seq: int) -> int:
        """The unwrapped position of 32-bit sequence number `seq`, taken as the one nearest `next`."""
        return self.next + (((seq - self.next) + _HALF) % _MOD - _HALF)


class TcpReassembler:
    """Turns TCP segments into in-order stream Payloads, one reassembler per capture.

    A stream key is ("tcp", src, dst, generation); the generation changes when a SYN with a new initial
    sequence number reuses a 4-tuple, so downstream parsers start afresh.
    """

    def __init__(self, max_buffered: int = MAX_BUFFERED) -> None:
        self.max_buffered = max_buffered
        self._dirs: dict[tuple[Endpoint, Endpoint], _Direction] = {}
        self._gens: dict[tuple[Endpoint, Endpoint], int] = {}

    def segment(
        self, src: Endpoint, dst: Endpoint, seq: int, flags: int, data: bytes, record: int, offset: int | None
    ) -> list[Payload]:
        """Take one segment (payload `data` at file `offset`) and return the bytes now in order."""
        out: list[Payload] = []
        k = (src, dst)
        d = self._dirs.get(k)
        if flags & TCP_SYN:
            if d is not None and d.isn == seq:
                pass  # a retransmitted SYN
            else:
                if d is not None:
                    self._drain(d, out, gaps=True)
                gen = self._gens.get(k, -1) + 1
                self._gens[k] = gen
                d = self._dirs[k] = _Direction(src, dst, seq, seq + 1, gen)
            seq = (seq + 1) % _MOD
        elif d is None:
            gen = self._gens.get(k, -1) + 1
            self._gens[k] = gen
            d = self._dirs[k] = _Direction(src, dst, seq, seq, gen)
        if data:
            start = d.unwrap(seq)
            if start == d.next and not d.pending:  # the common case: the next bytes, nothing buffered
                d.next = start + len(data)
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, src, dst, data, d.key, record, offset, ())))
            else:
                self._add(d, start, data, record, offset, out)
        if flags & (TCP_FIN | TCP_RST) and d.pending:
            self._drain(d, out, gaps=True)
        return out

    def _add(
        self, d: _Direction, start: int, data: bytes, record: int, offset: int | None, out: list[Payload]
    ) -> None:
        """Deliver or buffer a segment that is not simply the next in order."""
        end = start + len(data)
        if end <= d.next:
            msg = f"TCP retransmission of {len(data)} bytes already delivered"
            out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                            (note("tcp-retransmission", msg, offset),))))
            return
        d.counter += 1
        heapq.heappush(d.pending, (start, d.counter, data, record, offset))
        d.buffered += len(data)
        self._drain(d, out, gaps=False)

    def _drain(self, d: _Direction, out: list[Payload], gaps: bool) -> None:
        """Deliver buffered segments that are now in order.

        Missing ranges are skipped (with a tcp-gap note) when `gaps` is set, or while the buffer is over
        its bound.
        """
        pending = d.pending
        while pending:
            start, _, data, record, offset = pending[0]
            notes: tuple[Note, ...] = ()
            if start > d.next:
                if not gaps and d.buffered <= self.max_buffered:
                    return
                missing = start - d.next
                notes = (note("tcp-gap", f"{missing} bytes missing from the TCP stream {d.src} -> {d.dst}",
                              offset),)
                d.next = start
            heapq.heappop(pending)
            d.buffered -= len(data)
            end = start + len(data)
            if end <= d.next:
                msg = f"TCP retransmission of {len(data)} bytes already delivered"
                out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, b"", d.key, record, offset,
                                                notes + (note("tcp-retransmission", msg, offset),))))
                continue
            if start < d.next:
                cut = d.next - start
                msg = f"TCP retransmission: {cut} overlapping bytes trimmed"
                notes += (note("tcp-retransmission", msg, offset),)
                data = data[cut:]
                if offset is not None:
                    offset += cut
            d.next = end
            out.append(_tuple_new(Payload, (TRANSPORT_TCP, d.src, d.dst, data, d.key, record, offset, notes)))

    def flush(self) -> list[Payload]:
        """Deliver everything still buffered (end of capture), noting the gaps skipped."""
        out: list[Payload] = []
        for d in self._dirs.values():
            if d.pending:
                self._drain(d, out, gaps=True)
        return out
