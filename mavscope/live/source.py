"""Live sources: a receiver thread, a bounded queue, and an iterator of Records in arrival order.

`LiveSource` is the part every source shares. Its receiver thread does as little as it can (receive,
timestamp, enqueue) so that it gets back to the socket quickly; the consumer turns queue items into
`Record`s (`_record`) and feeds them to the same pipeline offline captures go through. The queue is
bounded by datagram count and bytes; what does not fit is dropped by the receiver and counted, never
silently. Kernel drops (the socket buffer overflowing before the receiver got to it) are counted by each
source from what the kernel reports.

Usage (the command line's `live`, or a TUI's follow mode)::

    src = UdpSource(parse_endpoint("14550"))
    src.open(); src.start()
    for rec in src.records(on_idle=flush):   # ends after src.stop() (from any thread or a signal handler)
        ...
    src.close()
"""

from __future__ import annotations

import queue
import select
import socket
import struct
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, NamedTuple

from mavscope.capture.base import LINKTYPE_ETHERNET, Record

DEFAULT_QUEUE_ITEMS = 200_000  # datagrams waiting for the decoder (10 s at 20,000 datagrams/s)
DEFAULT_QUEUE_BYTES = 64 << 20  # and at most this many payload bytes
PCAP_HEADER = 24  # a classic pcap file header, then 16 bytes before each record
PCAP_RECORD_HEADER = 16


_RECORD = struct.Struct("<IIII")  # a Chunk's record header: seconds, nanoseconds, captured and original length
_ETHER_V4_HEAD = 14 + 20 + 8  # the headers before a datagram's payload in a Chunk's packets
_ETHER_V6_HEAD = 14 + 40 + 8


class Chunk(NamedTuple):
    """Datagrams received in one batch by the native receiver (mavscope._native.Receiver): whole records
    of a nanosecond, Ethernet pcap (`records`, each the packet capture.synth.udp_packet makes), how many
    (`datagrams`) and their payload bytes (`size`, last as in every queue item)."""

    records: bytes
    datagrams: int
    size: int


def chunk_items(records: bytes | memoryview) -> Iterator[tuple[float, bytes, int]]:
    """(time, packet, payload bytes) of every record of a Chunk, in order; the time as the pcap reader
    computes it from the record (seconds + nanoseconds / 1e9)."""
    unpack = _RECORD.unpack_from
    pos = 0
    end = len(records)
    while pos + 16 <= end:
        sec, nsec, incl, _orig = unpack(records, pos)
        packet = bytes(records[pos + 16 : pos + 16 + incl])
        pos += 16 + incl
        head = _ETHER_V4_HEAD if packet[12:14] == b"\x08\x00" else _ETHER_V6_HEAD
        yield sec + nsec / 1_000_000_000, packet, len(packet) - head


def chunk_prefix(chunk: Chunk, items: int, size: int) -> Chunk:
    """The first datagrams of `chunk`, at most `items` of them and `size` payload bytes in all."""
    kept = bytearray()
    n = total = 0
    pos = 0
    for _t, packet, payload in chunk_items(chunk.records):
        if n >= items or total + payload > size:
            break
        end = pos + 16 + len(packet)
        kept += chunk.records[pos:end]
        pos = end
        n += 1
        total += payload
    return Chunk(bytes(kept), n, total)


@dataclass(frozen=True)
class LiveStats:
    """A snapshot of a source's counters."""

    received: int  # datagrams (or packets) taken from the kernel
    bytes: int  # their payload bytes (UDP payload; whole link-layer frames when sniffing)
    delivered: int  # records handed to the consumer
    queue_drops: int  # received but dropped because the queue was full
    kernel_drops: int | None  # dropped by the kernel before the receiver got them; None: unknown here

    @property
    def dropped(self) -> int:
        return self.queue_drops + (self.kernel_drops or 0)


class LiveSource:
    """A receiver thread filling a bounded queue, and `records()` draining it as numbered Records.

    Subclasses implement `open()` (sockets; errors raised there are the user's: bad port, no
    permission), `_receive()` (the thread body: call `self._offer(item, size)` per datagram until
    `self._stopping` is set, then return) and `_record(number, offset, item)`.
    """

    linktype = LINKTYPE_ETHERNET
    description = "live source"

    def __init__(self, max_items: int = DEFAULT_QUEUE_ITEMS, max_bytes: int = DEFAULT_QUEUE_BYTES) -> None:
        self.max_items = max_items
        self.max_bytes = max_bytes
        self._q: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._stopping = threading.Event()
        self._drain = True
        self._thread: threading.Thread | None = None
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self.error: BaseException | None = None  # what ended the receiver, if not stop()
        # written by the receiver thread only
        self.received = 0
        self.received_bytes = 0
        self.queue_drops = 0
        self._queued_bytes = 0
        # written by the consumer only
        self.delivered = 0
        self._delivered_bytes = 0
        self._next_offset = PCAP_HEADER
        self.t0: float | None = None  # time of the first record delivered
        self._closed = False
        self._kernel_at_close: int | None = None

    # -- life cycle ---------------------------------------------------------------------------------

    def open(self) -> None:
        """Create the sockets (raises MavscopeError with a one-line reason)."""

    def start(self) -> None:
        """Start the receiver thread (after open())."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name=f"mavscope {self.description}", daemon=True)
        self._thread.start()

    def stop(self, drain: bool = True) -> None:
        """Ask the receiver to stop; safe from any thread and from a signal handler (does not wait).

        `drain`: first take what the kernel already holds for the socket, so that nothing that
        arrived before the stop is lost; records() ends once the queue is empty.
        """
        self._drain = self._drain and drain
        if not self._stopping.is_set():
            self._stopping.set()
            try:
                self._wake_w.send(b"x")
            except OSError:
                pass

    def close(self, timeout: float = 5.0) -> None:
        """Stop, wait for the receiver thread, release the sockets."""
        self.stop(drain=False)
        if self._thread is not None:
            self._thread.join(timeout)
        if not self._closed:
            self._kernel_at_close = self._kernel_drops_now()  # the sockets' counters go with them
            self._closed = True
        self._close_sockets()
        for s in (self._wake_r, self._wake_w):
            s.close()

    @property
    def stopping(self) -> bool:
        """stop() was called."""
        return self._stopping.is_set()

    def stats(self) -> LiveStats:
        return LiveStats(self.received, self.received_bytes, self.delivered, self.queue_drops,
                         self.kernel_drops())

    def kernel_drops(self) -> int | None:
        """Datagrams the kernel dropped for this source's sockets; None where it cannot tell."""
        return self._kernel_at_close if self._closed else self._kernel_drops_now()

    def _kernel_drops_now(self) -> int | None:
        return None

    # -- the consumer side --------------------------------------------------------------------------

    def records(
        self, on_idle: Callable[[], None] | None = None, idle_interval: float = 0.25
    ) -> Iterator[Record]:
        """Records in arrival order, numbered from 1, until stop() (or the receiver fails: then its error).

        `on_idle` is called whenever the queue is empty (before waiting) and every `idle_interval`
        seconds while it stays empty: the place to flush output and files.
        """
        record = self._record
        for item in self._items(on_idle, idle_interval):
            if type(item) is Chunk:
                yield from self._chunk_records(item)
                continue
            self.delivered += 1
            self._delivered_bytes += item[-1]
            rec = record(self.delivered, self._next_offset + PCAP_RECORD_HEADER, item)
            self._next_offset += PCAP_RECORD_HEADER + len(rec.data)
            if self.t0 is None:
                self.t0 = rec.time
            yield rec
        if self.error is not None:
            raise self.error

    __iter__ = records

    def chunks(
        self, on_idle: Callable[[], None] | None = None, idle_interval: float = 0.25
    ) -> Iterator[Chunk]:
        """The queue as the native receiver filled it: Chunks of pcap records, in arrival order, until stop()
        (for the native walker, mavscope.native.live). Records are counted and numbered as records() would
        (the records of a Chunk are records `delivered - datagrams + 1` .. `delivered` after it is yielded).
        Only for a source that queues Chunks (`UdpSource.batched`)."""
        for item in self._items(on_idle, idle_interval):
            if type(item) is not Chunk:
                raise TypeError("chunks() needs a source whose receiver queues Chunks")
            self.delivered += item.datagrams
            self._delivered_bytes += item.size
            if self.t0 is None and item.datagrams:
                sec, nsec = _RECORD.unpack_from(item.records)[:2]
                self.t0 = sec + nsec / 1_000_000_000
            self._next_offset += len(item.records)
            yield item
        if self.error is not None:
            raise self.error

    def _items(self, on_idle: Callable[[], None] | None, idle_interval: float) -> Iterator[Any]:
        """Queue items in order until the receiver's end mark; `on_idle` while the queue is empty."""
        get = self._q.get
        empty = queue.Empty
        while True:
            try:
                item = get(block=False)
            except empty:
                if on_idle is not None:
                    on_idle()
                while True:
                    try:
                        item = get(timeout=idle_interval)
                        break
                    except empty:
                        if on_idle is not None:
                            on_idle()
            if item is None:
                return
            yield item

    def _chunk_records(self, chunk: Chunk) -> Iterator[Record]:
        for t, packet, payload in chunk_items(chunk.records):
            self.delivered += 1
            self._delivered_bytes += payload
            rec = Record(self.delivered, t, LINKTYPE_ETHERNET, packet, self._next_offset + PCAP_RECORD_HEADER,
                         len(packet))
            self._next_offset += PCAP_RECORD_HEADER + len(packet)
            if self.t0 is None:
                self.t0 = t
            yield rec

    # -- the receiver side --------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            self._receive()
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer, raised there
            self.error = exc
        finally:
            self._q.put(None)

    def _offer(self, item: tuple[Any, ...], size: int) -> None:
        """Queue one received item (its last element must be `size`); count it as dropped when full."""
        self.received += 1
        self.received_bytes += size
        if (self.received - self.queue_drops - self.delivered > self.max_items
                or self._queued_bytes - self._delivered_bytes + size > self.max_bytes):
            self.queue_drops += 1
            return
        self._queued_bytes += size
        self._q.put(item)

    def _offer_chunk(self, chunk: Chunk) -> None:
        """Queue a Chunk; the datagrams that do not fit are dropped and counted, as `_offer` does."""
        waiting = self.received - self.queue_drops - self.delivered  # before this chunk
        self.received += chunk.datagrams
        self.received_bytes += chunk.size
        room = self.max_items - waiting
        room_bytes = self.max_bytes - (self._queued_bytes - self._delivered_bytes)
        if chunk.datagrams > room or chunk.size > room_bytes:
            kept = chunk_prefix(chunk, max(room, 0), max(room_bytes, 0))
            self.queue_drops += chunk.datagrams - kept.datagrams
            chunk = kept
        if chunk.datagrams:
            self._queued_bytes += chunk.size
            self._q.put(chunk)

    def _receive(self) -> None:
        raise NotImplementedError

    def _record(self, number: int, offset: int, item: tuple[Any, ...]) -> Record:
        raise NotImplementedError

    def _close_sockets(self) -> None:
        pass


# Linux socket options the socket module does not name.
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)


def set_receive_buffer(sock: socket.socket, wanted: int) -> int:
    """Ask for a `wanted`-byte receive buffer, beyond net.core.rmem_max where allowed (CAP_NET_ADMIN);
    return what the kernel granted (its figure, which Linux doubles for bookkeeping)."""
    for opt in (SO_RCVBUFFORCE, socket.SO_RCVBUF):
        try:
            sock.setsockopt(socket.SOL_SOCKET, opt, wanted)
            break
        except OSError:
            continue
    return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)


def enable_option(sock: socket.socket, level: int, opt: int) -> bool:
    try:
        sock.setsockopt(level, opt, 1)
        return True
    except OSError:
        return False


def wait_readable(poller: select.poll, timeout_s: float) -> list[int]:
    """File descriptors ready to read (EINTR from a signal counts as none ready)."""
    try:
        return [fd for fd, _ in poller.poll(timeout_s * 1000)]
    except InterruptedError:
        return []
