"""The first stage of the pipeline: capture records -> transport payloads -> MAVLink frames.

`Dissector.run(records)` yields, in capture order, every MAVLink frame found (`Frame`) and every
problem that could not be attached to a frame (`Anomaly`), so nothing the input holds is lost.
`feed(record)` and `finish()` do the same one record at a time (live capture, the native fast path
handing records back); `passed(number, time, index)` is told of records dissected elsewhere (the
native engine, mavscope/native/walk.py), so that what follows them comes out as if they had been fed; and
`raw` (RawLink) is what a raw byte stream shares with the native walker, which writes the stream's clean
stretches itself: the frame counter, and whether the stream's framer is idle.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Iterator
from dataclasses import dataclass
from typing import final

from mavscope.capture.base import Record
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame, Signature, new_frame
from mavscope.mavlink.framing import (
    OK,
    Framer,
    StreamFramer,
    build_frame,
    has_char_tail,
    mcrf4xx,
    skipped_note,
    unpack_signature,
    unpack_v2,
)
from mavscope.mavlink.hidden import ACROSS, Hidden, Scanned, hidden_note, merged
from mavscope.mavlink.receivers import WILD, Port, Sockets, Waiting, across, split_note
from mavscope.notes import GivenUp, Note
from mavscope.pipeline.textrun import TextRun, is_text_entry
from mavscope.transport.base import TRANSPORT_RAW, TRANSPORT_TLOG, TRANSPORT_UDP, Payload
from mavscope.transport.decap import Decapsulator
from mavscope.transport.dispatch import RAW_STREAM, TABLES
from mavscope.transport.tcp import GAP, TcpReassembler
from mavscope.transport.wpa import WifiKey, Wpa
from mavscope.wire import SIGNATURE_LEN, STX_V2

# Ports MAVLink uses by convention (DOMAIN.md): the UDP ports bound to PortRole.MAVLINK in the transport's
# dispatch tables (mavscope.transport.dispatch UDP_PORTS; Decapsulator.mavlink_ports). Datagrams on them are
# taken for MAVLink even when no frame in them has a valid CRC; on any other port, a valid frame must have
# been seen first. MAVLINK_PORTS: the default tables' (a dissector's own are its decap.mavlink_ports).
MAVLINK_PORTS = TABLES.mavlink_ports()
# Sources of valid MAVLink remembered (Dissector.mavlink_endpoints); the native walker's MS_MAX_ENDPOINTS
# (src/mavscope_native/walk.h) is the same number (tests/pipeline/test_endpoint_bound.py checks it).
MAX_MAVLINK_ENDPOINTS = 16384


# a frame the receivers read that the framer does not show: (its Hidden by position in the datagram, the bytes
# it is in, its position there, file offset, the earlier records it began in or None, its notes)
Placed = tuple[Hidden, bytes, int, "int | None", "tuple[int, ...] | None", list[Note]]
_CUT = frozenset({"record-snapped", "record-truncated", "malformed-packet"})  # notes of a payload cut short


@final  # never subclassed: consumers tell it from a Frame with `type(item) is Anomaly`
@dataclass(frozen=True, slots=True)
class Anomaly:
    """Notes that belong to no MAVLink frame (a malformed packet, garbage at the end of a stream)."""

    record: int
    notes: tuple[Note, ...]


class Receivers(dict[int, Port]):
    """The UDP receivers in a frame, by port (mavlink.receivers.Sockets.ports), as the native walker is given
    them: it hands back every datagram to one of these ports, and every record while `hand_back` (a TCP hole
    waits, and any record's time may end the wait: TcpReassembler.tick, as `feed` does it), so both engines
    give a hole up at the same record."""

    __slots__ = ("tcp",)

    def __init__(self, tcp: TcpReassembler) -> None:
        super().__init__()
        self.tcp = tcp

    @property
    def hand_back(self) -> bool:
        return self.tcp.waiting


class RawLink:
    """What a raw byte stream's dissection shares with the native walker, which writes the stream's clean
    stretches itself (mavscope/native/walk.py; docs/native.md says the rule): `frames`, the frames of the
    stream numbered so far by either engine (the walker reads it before each step and sets it after), and
    `held`: -1 while the stream's framer is idle (it holds no byte, no note and no receiver out of step: fed
    more bytes at a frame boundary, it gives what a framer that had read everything before would), else how
    many of the last bytes it was fed it has still to read (it goes on from there when fed more; the walker
    then hands back the next piece too)."""

    __slots__ = ("frames", "streams")

    def __init__(self, streams: dict[Hashable, StreamFramer]) -> None:
        self.frames = 0
        self.streams = streams

    @property
    def held(self) -> int:
        sf = self.streams.get(RAW_STREAM)
        if sf is None or not (sf.buf or sf.pending or sf.walking):
            return -1
        return len(sf.buf) - sf.start


class Dissector:
    """Finds and checks the MAVLink frames of a capture. One instance per capture (it keeps stream state)."""

    def __init__(self, dialect: Dialect, wifi: tuple[WifiKey, ...] = ()) -> None:
        """`wifi`: the WPA2 networks' keys its 802.11 frames are decrypted with."""
        self.dialect = dialect
        self.messages = dialect.messages
        self.framer = Framer(dialect.messages)
        self.decap = Decapsulator(wpa=Wpa(wifi) if wifi else None)
        self.streams: dict[Hashable, StreamFramer] = {}
        # endpoints that have carried a CRC-valid frame: their datagrams are MAVLink even when damaged; at most
        # MAX_MAVLINK_ENDPOINTS, the first ones kept (_learn: a flood of spoofed sources churns nothing out)
        self.mavlink_endpoints: set[Endpoint] = set()
        self._said: list[Note] = []
        self.endpoints_given_up = GivenUp(f"sources of valid MAVLink (at most {MAX_MAVLINK_ENDPOINTS:,} remembered)",
                                          "datagrams", self._said)
        # UDP receivers (MAVLink's C library behind a socket) in a frame where the last datagram to them
        # ended (mavscope.mavlink.receivers), by port: the next datagram to them goes on with it. The native
        # walker hands every datagram to one of these ports back here.
        self.sockets = Sockets()
        self.sockets.ports = self.receivers = Receivers(self.decap.tcp)
        self._record = 0
        self._index = 0
        self.raw = RawLink(self.streams)  # frames of a raw byte stream so far (they are numbered 1..N)
        self._time: float | None = None
        self._text = TextRun()  # non-MAVLink tlog entries, reported as one anomaly per run
        # record -> the last frame index it gave, for the records a later one may date frames by (_later): kept
        # while TCP reassembly holds bytes beyond a hole or a stream framer holds bytes readable at that record
        self._indices: dict[int, int] = {}
        self._prune_at = 0  # (the size of _indices past which what nothing can date by any more is dropped)
        self._held = False  # a stream framer fed in this record holds bytes readable at it

    def run(self, records: Iterable[Record]) -> Iterator[Frame | Anomaly]:
        """Every frame and anomaly of the capture, in order."""
        feed = self.feed
        for rec in records:
            yield from feed(rec)
        yield from self.finish()

    def feed(self, rec: Record) -> Iterator[Frame | Anomaly]:
        """The frames and anomalies that record `rec` completes (a stream may hold bytes for later)."""
        text = self._text
        if text:
            if is_text_entry(rec):
                if text.add(rec):
                    yield self._take_text()
                return
            yield self._take_text()
        elif is_text_entry(rec):
            text.add(rec)
            return
        number = rec.number
        time = rec.time
        self._record = number
        self._time = time
        messages = self.messages
        endpoints = self.mavlink_endpoints
        index = 0
        self._held = False
        for p in self.decap.feed(rec):
            if p.stream is not None:
                self._index = index
                yield from self._stream(p)
                index = self._index
                continue
            # Fast path: a datagram that is a run of clean v2 frames (known message, good CRC,
            # no unknown flags). Anything else goes to the general scanner from where it stops.
            data = p.data
            n = len(data)
            pos = 0
            if not p.notes and p.span is None and not (self.receivers and p.dst is not None
                                                      and p.dst.port in self.receivers):
                src = p.src
                base = p.offset
                while pos + 12 <= n and data[pos] == STX_V2:
                    stx, length, iflags, cflags, seq, sysid, compid, lo, hi = unpack_v2(data, pos)
                    end = pos + 10 + length
                    size = length + (25 if iflags & 1 else 12)
                    if iflags > 1 or pos + size > n:
                        break
                    md = messages.get(lo | (hi << 16))
                    if md is None or length > md.length or (md.chars and has_char_tail(md, data, pos + 10, end)):
                        break  # (the general scanner notes bytes after a string's NUL)
                    crc = data[end] | (data[end + 1] << 8)
                    if mcrf4xx(md.crc_extra_byte, mcrf4xx(data[pos + 1 : end])) != crc:
                        break
                    raw = data[pos : pos + size] if size != n else data
                    sig = None
                    if iflags:
                        link_id, ts, value = unpack_signature(raw, size - SIGNATURE_LEN)
                        sig = Signature(link_id, int.from_bytes(ts, "little"), value)
                    index += 1
                    yield new_frame(number, index, time, p.transport, src, p.dst, None if base is None else base + pos,
                                    raw, 2, length, iflags, cflags, seq, sysid, compid, md.id, crc, OK, md, sig, (),
                                    None)
                    pos += size
                if pos and src is not None and src not in endpoints and not self._learn(src) and self._said:
                    yield Anomaly(number, tuple(self._said))  # (the datagram's frames went out above)
                    self._said.clear()
                if pos == n:
                    continue
            self._index = index
            yield from self._datagram(p, pos)
            index = self._index
        tcp = self.decap.tcp
        if tcp.waiting:  # a TCP hole waits: this record's time (whatever it carried) may end the wait
            self._index = index
            for p in tcp.tick(number, time):
                yield from self._stream(p) if p.stream is not None else self._datagram(p, 0)
            index = self._index
        ended = tcp.ended
        if ended:  # TCP streams that ended or were released: decide what their framers still hold
            self._index = index
            while ended:
                key = ended.popleft()
                if key in self.streams:
                    yield from self._finish(key)
            index = self._index
        if self._indices or self._held or tcp.holding:  # (clean traffic: nothing held, nothing to number later)
            self._hold(number, index, tcp.holding)

    def finish(self) -> Iterator[Frame | Anomaly]:
        """The end of the capture: what TCP reassembly and the stream framers still hold."""
        if self._text:
            yield self._take_text()
        for p in self.decap.flush():
            yield from self._stream(p) if p.stream is not None else self._datagram(p, 0)
        for key in list(self.streams):
            yield from self._finish(key)

    def passed(self, number: int, time: float | None, index: int | None = None) -> list[Anomaly]:
        """Records up to `number` were dissected elsewhere (the native engine: clean datagrams and tlog
        entries, mavscope/native/walk.py): keep the state `feed` would have kept from them. Returns what `feed`
        would have reported first: a run of tlog text entries held from before them ends here. Frames
        completed at the end of the capture belong to record `number` and its `time`; `index`, when not
        None, is the frame index the general scanner would have left (records with a MAVLink 1 frame). No TCP
        hole waits over such records (the walker hands every record back while one does: Receivers.hand_back),
        so the reassembler's clock needs no tick here."""
        out = [self._take_text()] if self._text else []
        self._record = number
        self._time = time
        if index is not None:
            self._index = index
        return out

    def _take_text(self) -> Anomaly:
        record, text_note = self._text.take()
        return Anomaly(record, (text_note,))

    def _learn(self, src: Endpoint) -> bool:
        """Remember `src` as a source of valid MAVLink (False, and a give-up said onto `_said`, when the set
        is full: the sources already known stay; what the newcomer loses is only that a datagram of it with
        no valid frame, on a port MAVLink does not use by convention, is not scanned as MAVLink).

        The native walker keeps the same bound: it hands back a record from a source it does not know once
        the set is full (mavscope/native/walk.py), so both engines note the same records."""
        if len(self.mavlink_endpoints) < MAX_MAVLINK_ENDPOINTS:
            self.mavlink_endpoints.add(src)
            return True
        self.endpoints_given_up.add(f"a datagram of {src.text}, a source not remembered: its datagrams without a "
                                    "valid frame are scanned as MAVLink only on MAVLink's ports")
        return False

    def _trusted(self, p: Payload) -> bool:
        if p.transport == TRANSPORT_TLOG:
            return True
        if p.src in self.mavlink_endpoints or p.dst in self.mavlink_endpoints:
            return True
        ports = self.decap.mavlink_ports
        return any(ep is not None and ep.port in ports for ep in (p.src, p.dst))

    def _datagram(self, p: Payload, start: int) -> Iterator[Frame | Anomaly]:
        """The general path: scan a datagram from `start` (the frames before it were clean)."""
        data = p.data
        udp = p.transport == TRANSPORT_UDP and p.dst is not None
        waiting = udp and self.receivers and p.dst.port in self.receivers  # type: ignore[union-attr]
        if not data:
            if p.notes:
                yield Anomaly(p.record, p.notes)
            return
        found, skipped, _ = self.framer.scan(data, start, len(data), True)
        # (a receiver in a frame is given MAVLink: it reads the datagram on with it)
        if not start and not waiting and not any(f[2] is OK for f in found) and not self._trusted(p):
            # No valid frame and no reason to expect MAVLink here: some other protocol.
            if p.notes:
                yield Anomaly(p.record, p.notes)
            return
        pending: list[Note] = list(p.notes)
        if p.src is not None and found and found[0][2] is OK and p.src not in self.mavlink_endpoints:
            if not self._learn(p.src):
                pending.extend(self._said)
                self._said.clear()
        base = p.offset
        sk = 0
        messages = self.messages
        hidden, given_up = self._receivers(p, data, found, skipped, base, udp)
        pending.extend(given_up)  # (on the record's first frame, as its own notes)
        by_id = {id(x[0]): x for x in hidden}
        for (pos, size, status, crc), h in merged(found, [x[0] for x in hidden]):
            while sk < len(skipped) and skipped[sk][0] < pos:
                s_pos, s_count = skipped[sk]
                sk += 1
                pending.append(skipped_note(s_count, None if base is None else base + s_pos))
            self._index += 1
            span = None
            if h is None:
                offset = None if base is None else base + pos
                frame_buf = data
            else:
                _, frame_buf, pos, offset, span, notes = by_id[id(h)]
                pending.extend(notes)
                if span is not None:
                    span = (*span, self._record)
            if span is None:  # reassembled from IP fragments: their records
                span = p.span
            frame = build_frame(
                frame_buf, pos, size, status, crc, messages, self._record, self._index, self._time, p.transport,
                p.src, p.dst, offset, tuple(pending) if pending else (), span,
            )
            pending = []
            yield frame
        # what no frame carried: the record's notes when no frame came, skipped bytes after the last frame
        pending.extend(skipped_note(c, None if base is None else base + s) for s, c in skipped[sk:])
        if pending:
            yield Anomaly(p.record, tuple(pending))

    def _receivers(self, p: Payload, data: bytes, found: list[Scanned], skipped: list[tuple[int, int]],
                   base: int | None, udp: bool) -> tuple[list[Placed], list[Note]]:
        """The frames the receivers a datagram reaches read that the framer does not show, each with the bytes
        it is in, its position there, file offset, the earlier records it began in and its notes; and the
        notes of what the receivers' bounds gave up. A UDP datagram goes on with each receiver state it
        reaches (mavscope.mavlink.receivers: a socket, not an address), walked once per distinct state."""
        cand, rec = self.framer.candidate, self._record
        if not udp:
            hidden = across(cand, data, found, skipped, None, rec, base)[2]
            return [(h, data, h[0][0], None if base is None else base + h[0][0], None,
                     [hidden_note(h, None if base is None else base + h[0][0])]) for h in hidden], []
        dst: Endpoint = p.dst  # type: ignore[assignment]  # (udp: not None)
        walks: dict[int, tuple[Waiting | None, list[str], tuple[bytes, int, list[Hidden], Waiting | None]]] = {}
        left: dict[str, Waiting | None] = {}
        for key, w in self.sockets.reach(dst):
            walk = walks.get(id(w))
            if walk is None:
                walk = walks[id(w)] = (w, [], across(cand, data, found, skipped, w, rec, base, dst.text))
            walk[1].append(key)
            left[key] = walk[2][3]
        if any(n.code in _CUT for n in p.notes):  # a capture that lost the datagram's end: the state is unknown
            left = dict.fromkeys(left)
        said = self.sockets.settle(dst, left)
        placed: list[Placed] = []
        inside: set[int] = set()
        split: set[tuple[tuple[int, ...], int | None, bytes]] = set()
        for w, keys, (buf, t, hidden, _) in walks.values():
            for h in hidden:
                bpos, size = h[0][0], h[0][1]
                pos = bpos - t
                hd: Hidden = ((pos, *h[0][1:]), h[1] - t, h[2], h[3])
                if pos >= 0:
                    if pos not in inside:
                        inside.add(pos)
                        offset = None if base is None else base + pos
                        placed.append((hd, data, pos, offset, None, [hidden_note(hd, offset)]))
                    continue
                offset, records, dsts = w.locate(bpos)  # type: ignore[union-attr]  # (t > 0: there is one)
                seen = (records, offset, buf[bpos:bpos + size])
                if seen in split:
                    continue
                split.add(seen)
                notes = [split_note(hd, -pos, records, tuple(dict.fromkeys((*dsts, dst.text))), offset,
                                    keys == [WILD])]
                if h[1] != h[0][0] or h[2] != ACROSS:  # the receiver parted from the framer before it, too
                    notes.append(hidden_note(hd, offset))
                placed.append((hd, buf, bpos, offset, records, notes))
        return placed, said

    def _emit(self, sf: StreamFramer, p_transport: str, src: Endpoint | None, dst: Endpoint | None,
              final: bool) -> Iterator[Frame | Anomaly]:
        found, orphans = sf.take(final)
        raw = p_transport == TRANSPORT_RAW
        for buf, pos, size, status, crc, off, records, notes, done in found:
            span: tuple[int, ...] | None
            time = self._time
            if raw:
                # A raw stream has no records of its own (its chunks are the reader's), so its frames are
                # numbered 1..N and each is its own "record": frame 999 is 999, not 1.999.
                self.raw.frames += 1
                record, index, span = self.raw.frames, 1, None
            else:
                # a frame is the record's that completed it (its last byte, readable in order there: after
                # a hole the capture missed, an earlier record than this one), with the records holding it
                record, time = done
                if record == self._record:
                    self._index += 1
                    index = self._index
                else:
                    index = self._later(record)
                span = None if records == (record,) else records
            yield build_frame(
                buf, pos, size, status, crc, self.messages, record, index, time,
                p_transport, src, dst, off, notes, span,
            )
        if orphans:
            yield Anomaly(self.raw.frames if raw else self._record, tuple(orphans))

    def _later(self, record: int) -> int:
        """The index of one more frame of `record`, an earlier record than the one read: a frame a TCP hole held
        back, or one a hole or the stream's end cut (`_hold` kept the last index `record` gave)."""
        index = self._indices.get(record, 0) + 1
        self._indices[record] = index
        return index

    def _hold(self, number: int, index: int, holding: bool) -> None:
        """Record `number` gave frames up to `index`: remember it while a later record may date frames by it
        (bytes readable at it that a stream framer holds, or TCP reassembly holds bytes beyond a hole, which
        it may give out dated by a record of the hole's lifetime); forget what nothing can date by any more.

        The bound is the holes' lifetime and the bytes the framers hold, not a count: a record forgotten
        while something could still be dated by it would number a frame twice."""
        later = self._indices
        if index and (holding or self._held):
            later[number] = index
        if holding or len(later) <= self._prune_at:
            return
        # TCP reassembly holds nothing: only the bytes the stream framers hold can still be dated by a record
        live = {ready[0] for sf in self.streams.values() for _, _, _, ready in sf.segs}
        for r in [r for r in later if r not in live]:
            del later[r]
        self._prune_at = max(2 * len(later), len(self.streams)) + 64  # (amortised: a walk per as many records)

    def _stream(self, p: Payload) -> Iterator[Frame | Anomaly]:
        sf = self.streams.get(p.stream)
        if sf is not None and p.notes and any(n.code == GAP for n in p.notes):
            # a hole the capture missed: what the framer holds ends before it (a frame it cut is truncated)
            yield from self._emit(sf, p.transport, p.src, p.dst, True)
        if not p.data:
            # notes on a segment that added no bytes (a retransmission, a conflicting one, a suspicious SYN):
            # its record's, now, not the next frame's of the stream (which may come records later)
            if p.notes:
                yield Anomaly(p.record, p.notes)
            return
        if sf is None:
            sf = self.streams[p.stream] = StreamFramer(self.framer, (p.stream, p.transport, p.src, p.dst))
            # A raw file is MAVLink by the user's word; a TCP stream proves it with a valid frame.
            sf.trusted = p.transport == TRANSPORT_RAW
        sf.feed(p.data, p.record, p.offset, p.notes, p.ready or (self._record, self._time))
        yield from self._emit(sf, p.transport, p.src, p.dst, False)
        if sf.segs and not self._held and p.transport != TRANSPORT_RAW:
            # bytes readable at this record held for a later one (a frame begun): it may date a frame a hole or
            # the stream's end cuts
            rec = self._record
            self._held = any(ready[0] == rec for _, _, _, ready in sf.segs)

    def _finish(self, key: Hashable) -> Iterator[Frame | Anomaly]:
        sf = self.streams.pop(key)
        transport: str
        src: Endpoint | None
        dst: Endpoint | None
        _, transport, src, dst = sf.key  # type: ignore[misc]  # the key _stream made: (stream, transport, src, dst)
        yield from self._emit(sf, transport, src, dst, True)
