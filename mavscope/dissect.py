"""The offline pipeline: capture records -> transport payloads -> MAVLink frames.

`Dissector.run(reader)` yields, in capture order, every MAVLink frame found (`Frame`) and every
problem that could not be attached to a frame (`Anomaly`), so nothing the input holds is lost.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Iterator
from dataclasses import dataclass
from typing import final

from mavscope.capture.base import Record
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import SIGNATURE_LEN, STX_V2, Frame, Signature
from mavscope.mavlink.framing import (
    OK,
    Framer,
    StreamFramer,
    build_frame,
    mcrf4xx,
    skipped_note,
    unpack_signature,
    unpack_v2,
)
from mavscope.notes import Note
from mavscope.transport.base import TRANSPORT_RAW, TRANSPORT_TLOG, Payload
from mavscope.transport.decap import Decapsulator

_new = tuple.__new__

# Ports MAVLink uses by convention (DOMAIN.md). Datagrams on them are taken for MAVLink even when no
# frame in them has a valid CRC; on any other port, a valid frame must have been seen first.
MAVLINK_PORTS = frozenset({14550, 14540, 14555, 14557, 14560, 14580, 18570, 5760, 5761, 5762, 5763})


@final  # never subclassed: consumers tell it from a Frame with `type(item) is Anomaly`
@dataclass(frozen=True, slots=True)
class Anomaly:
    """Notes that belong to no MAVLink frame (a malformed packet, garbage at the end of a stream)."""

    record: int
    notes: tuple[Note, ...]


def _port(endpoint: str | None) -> int:
    if not endpoint:
        return -1
    try:
        return int(endpoint.rsplit(":", 1)[1])
    except (IndexError, ValueError):
        return -1


class Dissector:
    """Finds and checks the MAVLink frames of a capture. One instance per capture (it keeps stream state)."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.messages = dialect.messages
        self.framer = Framer(dialect.messages)
        self.decap = Decapsulator()
        self.streams: dict[Hashable, StreamFramer] = {}
        self.mavlink_endpoints: set[str] = set()
        self._record = 0
        self._index = 0
        self._time: float | None = None

    def run(self, records: Iterable[Record], final: bool = True) -> Iterator[Frame | Anomaly]:
        """Every frame and anomaly of the capture, in order.

        With `final` False the capture goes on after `records`: TCP and stream state is kept for more
        (`feed` and `finish` are the record-at-a-time face of this).
        """
        feed = self.decap.feed
        messages = self.messages
        endpoints = self.mavlink_endpoints
        for rec in records:
            number = rec[0]
            time = rec[1]
            self._record = number
            self._time = time
            index = 0
            for p in feed(rec):
                if p[4] is not None:
                    self._index = index
                    yield from self._stream(p, final=False)
                    index = self._index
                    continue
                # Fast path: a datagram that is a run of clean v2 frames (known message, good CRC,
                # no unknown flags). Anything else goes to the general scanner from where it stops.
                data = p[3]
                n = len(data)
                pos = 0
                if not p[7]:
                    src = p[1]
                    while pos + 12 <= n and data[pos] == STX_V2:
                        stx, length, iflags, cflags, seq, sysid, compid, lo, hi = unpack_v2(data, pos)
                        end = pos + 10 + length
                        size = length + (25 if iflags & 1 else 12)
                        if iflags > 1 or pos + size > n:
                            break
                        md = messages.get(lo | (hi << 16))
                        if md is None or length > md.length:
                            break
                        crc = data[end] | (data[end + 1] << 8)
                        if mcrf4xx(md.crc_extra_byte, mcrf4xx(data[pos + 1 : end])) != crc:
                            break
                        raw = data[pos : pos + size] if size != n else data
                        sig = None
                        if iflags:
                            link_id, ts, value = unpack_signature(raw, size - SIGNATURE_LEN)
                            sig = Signature(link_id, int.from_bytes(ts, "little"), value)
                        index += 1
                        yield _new(Frame, (
                            number, index, time, p[0], src, p[2], None if p[6] is None else p[6] + pos, raw, 2,
                            length, iflags, cflags, seq, sysid, compid, md.id, crc, OK, md, sig, (), None, None,
                        ))
                        pos += size
                    if pos and src is not None and src not in endpoints:
                        endpoints.add(src)
                    if pos == n:
                        continue
                self._index = index
                yield from self._datagram(p, pos)
                index = self._index
        if not final:
            return
        for p in self.decap.flush():
            yield from self._stream(p, final=False) if p.stream is not None else self._datagram(p, 0)
        for key in list(self.streams):
            yield from self._finish(key)

    def feed(self, record: Record) -> list[Frame | Anomaly]:
        """The frames and anomalies `record` yields now; stream and TCP state carry over to the next."""
        return list(self.run((record,), final=False))

    def finish(self) -> list[Frame | Anomaly]:
        """End of capture: what TCP reassembly and the stream framers still hold."""
        return list(self.run((), final=True))

    def passed(self, number: int, time: float | None, index: int | None = None) -> None:
        """Record `number` was dissected elsewhere (the native walker, mavscope/native.py): keep the state
        this dissector would have kept from it, the record and time that frames completed at the end of
        the capture belong to, and `index` when not None (what the general scanner leaves in `_index`)."""
        self._record = number
        self._time = time
        if index is not None:
            self._index = index

    def _trusted(self, p: Payload) -> bool:
        if p.transport == TRANSPORT_TLOG:
            return True
        if p.src in self.mavlink_endpoints or p.dst in self.mavlink_endpoints:
            return True
        return _port(p.src) in MAVLINK_PORTS or _port(p.dst) in MAVLINK_PORTS

    def _datagram(self, p: Payload, start: int) -> Iterator[Frame | Anomaly]:
        """The general path: scan a datagram from `start` (the frames before it were clean)."""
        data = p.data
        if not data:
            if p.notes:
                yield Anomaly(p.record, p.notes)
            return
        found, skipped, _ = self.framer.scan(data, start, len(data), True)
        if not start and not any(f[2] is OK for f in found) and not self._trusted(p):
            # No valid frame and no reason to expect MAVLink here: some other protocol.
            if p.notes:
                yield Anomaly(p.record, p.notes)
            return
        if p.src is not None and found and found[0][2] is OK:  # found is empty for a stray byte or two
            self.mavlink_endpoints.add(p.src)
        base = p.offset
        pending: list[Note] = list(p.notes)
        sk = 0
        messages = self.messages
        for pos, size, status, crc in found:
            while sk < len(skipped) and skipped[sk][0] < pos:
                s_pos, s_count = skipped[sk]
                sk += 1
                pending.append(skipped_note(s_count, None if base is None else base + s_pos))
            self._index += 1
            frame = build_frame(
                data, pos, size, status, crc, messages, self._record, self._index, self._time, p.transport,
                p.src, p.dst, None if base is None else base + pos, tuple(pending) if pending else (), None,
            )
            pending = []
            yield frame
        if sk < len(skipped):
            yield Anomaly(
                p.record,
                tuple(skipped_note(c, None if base is None else base + s) for s, c in skipped[sk:]),
            )

    def _emit(self, sf: StreamFramer, p_transport: str, src: str | None, dst: str | None,
              final: bool) -> Iterator[Frame | Anomaly]:
        found, orphans = sf.take(final)
        for buf, pos, size, status, crc, off, span, notes in found:
            self._index += 1
            yield build_frame(
                buf, pos, size, status, crc, self.messages, self._record, self._index, self._time,
                p_transport, src, dst, off, notes, span,
            )
        if orphans:
            yield Anomaly(self._record, tuple(orphans))

    def _stream(self, p: Payload, final: bool) -> Iterator[Frame | Anomaly]:
        sf = self.streams.get(p.stream)
        if sf is None:
            sf = self.streams[p.stream] = StreamFramer(self.framer, (p.stream, p.transport, p.src, p.dst))
            # A raw file is MAVLink by the user's word; a TCP stream proves it with a valid frame.
            sf.trusted = p.transport == TRANSPORT_RAW
        sf.feed(p.data, p.record, p.offset, p.notes)
        yield from self._emit(sf, p.transport, p.src, p.dst, final)

    def _finish(self, key: Hashable) -> Iterator[Frame | Anomaly]:
        sf = self.streams.pop(key)
        transport: str
        src: str | None
        dst: str | None
        _, transport, src, dst = sf.key  # type: ignore[misc]  # the key _stream made: (stream, transport, src, dst)
        yield from self._emit(sf, transport, src, dst, True)
