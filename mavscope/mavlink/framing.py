"""Finding MAVLink frames in datagrams and byte streams.

A candidate frame starts at an STX byte (0xFE v1, 0xFD v2); its LEN byte gives its size. It is
accepted when:
- its CRC (with the message's CRC_EXTRA) is correct; or
- its CRC is bad or cannot be checked (unknown message id), and it ends exactly where the data ends or
  where another CRC-valid frame begins. A false STX inside a payload almost never passes either test,
  so resynchronisation does not produce phantom frames.
Anything else is skipped one byte at a time, and the skipped bytes are reported in a note. In a
datagram a frame cut short by the end of the datagram is reported as truncated; in a stream the
framer waits for more bytes, and only the end of the stream truncates.

Datagrams with no CRC-valid frame are taken for MAVLink only when `trusted` (a well-known MAVLink
port, a tlog entry, or an endpoint that has carried valid frames before): otherwise a DNS reply that
happens to start with 0xFD would become a "frame with a bad CRC".
"""

from __future__ import annotations

import re
import struct
from collections.abc import Hashable

from fastcrc import crc16

from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import MessageDef, char_tail
from mavscope.mavlink.frame import IFLAG_ENCRYPTION_MASK, KNOWN_IFLAGS, CrcStatus, Frame, Signature, new_frame
from mavscope.mavlink.hidden import Receiver, Scanned, Walking, hidden_frames, hidden_note, merged
from mavscope.notes import Note, note
from mavscope.wire import HEADER_V1, HEADER_V2, IFLAG_SIGNED, SIGNATURE_LEN, STX_V1, STX_V2, frame_size

mcrf4xx = crc16.mcrf4xx
unpack_v2 = struct.Struct("<BBBBBBBHB").unpack_from
_V1 = struct.Struct("<BBBBBB").unpack_from
_CRC = struct.Struct("<H").unpack_from
unpack_signature = struct.Struct("<B6s6s").unpack_from

OK = CrcStatus.OK
BAD = CrcStatus.BAD
UNCHECKED = CrcStatus.UNCHECKED
TRUNCATED = CrcStatus.TRUNCATED

# a frame StreamFramer.take found: (buf, pos, size, status, crc, offset, span, notes, done): span the records
# holding its bytes, in record order; done the (record, time) its last byte became readable at (its piece's)
StreamPiece = tuple[bytes, int, int, CrcStatus, int | None, int | None, tuple[int, ...], tuple[Note, ...],
                    tuple[int, float | None]]
Ready = tuple[int, float | None]  # the record (and its capture time) at which a stream's piece became readable


def _next_stx(buf: bytes, start: int, end: int) -> int:
    """Position of the first STX byte in buf[start:end], or `end`.

    The work is proportional to the distance covered, not to what lies beyond: the two bytes are looked
    for in windows that grow from STX_WINDOW (searching each to `end` cost a scan of the whole rest for
    the byte that is absent, at every byte of a run of the other one: quadratic).
    """
    step = STX_WINDOW
    while start < end:
        stop = start + step if start + step < end else end
        a = buf.find(b"\xfd", start, stop)
        b = buf.find(b"\xfe", start, stop if a < 0 else a)
        if b >= 0:
            return b
        if a >= 0:
            return a
        start = stop
        step <<= 2
    return end


def _crc_status(buf: bytes, pos: int, hlen: int, length: int, md: MessageDef | None) -> tuple[CrcStatus, int]:
    end = pos + hlen + length
    crc = buf[end] | (buf[end + 1] << 8)
    if md is None:
        return UNCHECKED, crc
    calc = mcrf4xx(md.crc_extra_byte, mcrf4xx(buf[pos + 1 : end]))
    return (OK if calc == crc else BAD), crc


VALID, INVALID, NEED_MORE = 1, 0, -1
STX_WINDOW = 16  # bytes _next_stx looks at first
_RUNS = {STX_V2: re.compile(b"\xfd+").match, STX_V1: re.compile(b"\xfe+").match}  # a run of one STX byte


def _check_at(buf: bytes, pos: int, end: int, messages: dict[int, MessageDef]) -> int:
    """VALID when a complete CRC-valid frame starts at `pos`; NEED_MORE when buf[pos:end] is too short
    to tell; INVALID otherwise. Used to confirm where a damaged frame ends."""
    if pos >= end:
        return NEED_MORE
    b = buf[pos]
    if b != STX_V2 and b != STX_V1:
        return INVALID
    if pos + 3 > end:
        return NEED_MORE
    size = frame_size(buf, pos)
    if pos + size > end:
        return NEED_MORE
    if b == STX_V2:
        md = messages.get(buf[pos + 7] | (buf[pos + 8] << 8) | (buf[pos + 9] << 16))
        hlen = HEADER_V2
    else:
        md = messages.get(buf[pos + 5])
        hlen = HEADER_V1
    if md is None:
        return INVALID
    return VALID if _crc_status(buf, pos, hlen, buf[pos + 1], md)[0] is OK else INVALID


def _cut_short(buf: bytes, start: int, valid: int, messages: dict[int, MessageDef]) -> bool:
    """True when skipped bytes buf[start:valid] are a frame cut short by the valid frame at `valid`.

    It takes a whole header with a plausible content (a known message id whose length fits the LEN
    byte, no unknown flags) claiming the bytes where the valid frame begins: a frame that lost bytes on
    a serial link. Anything less plausible stays skipped bytes, so payload bytes that merely look like
    an STX do not become phantom frames.
    """
    b = buf[start]
    length = buf[start + 1] if start + 1 < valid else -1
    if b == STX_V2:
        if valid - start < HEADER_V2 or buf[start + 2] & ~KNOWN_IFLAGS:
            return False
        md = messages.get(buf[start + 7] | (buf[start + 8] << 8) | (buf[start + 9] << 16))
        plausible = md is not None and 0 < length <= md.length
    elif b == STX_V1:
        if valid - start < HEADER_V1:
            return False
        md = messages.get(buf[start + 5])
        plausible = md is not None and length == md.base_length
    else:
        return False
    return plausible and start + frame_size(buf, start) > valid


class Framer:
    """Frame finder over one dialect. `parse_datagram` is stateless; `StreamFramer` keeps stream state."""

    def __init__(self, messages: dict[int, MessageDef]) -> None:
        self.messages = messages

    def candidate(self, buf: bytes, pos: int, end: int) -> tuple[int, CrcStatus, int | None] | None:
        """Size, CRC verdict and CRC of the frame at `pos`; None if fewer than 3 bytes are there.

        A frame running past `end` is TRUNCATED with size = the bytes present.
        """
        if pos + 3 > end:
            return None
        size = frame_size(buf, pos)
        if pos + size > end:
            return end - pos, TRUNCATED, None
        if buf[pos] == STX_V2:
            md = self.messages.get(buf[pos + 7] | (buf[pos + 8] << 8) | (buf[pos + 9] << 16))
            status, crc = _crc_status(buf, pos, HEADER_V2, buf[pos + 1], md)
        else:
            md = self.messages.get(buf[pos + 5])
            status, crc = _crc_status(buf, pos, HEADER_V1, buf[pos + 1], md)
        return size, status, crc

    def scan(
        self, buf: bytes, start: int, end: int, final: bool
    ) -> tuple[list[tuple[int, int, CrcStatus, int | None]], list[tuple[int, int]], int]:
        """Scan buf[start:end] for frames.

        Returns (frames as (pos, size, status, crc), skipped runs as (pos, count), resume position).
        With `final` False, scanning stops where more bytes are needed to decide (a stream); with
        `final` True (a datagram, or the end of a stream) everything is decided.
        """
        frames: list[tuple[int, int, CrcStatus, int | None]] = []
        skipped: list[tuple[int, int]] = []
        messages = self.messages
        pos = start
        skip_from = -1
        # The first position >= valid_from where a CRC-valid frame starts (`end`: none), as far as known.
        # It only moves forward with `pos`, so each position is checked once (not once per earlier STX).
        valid_from = valid_at = end
        run_to = -1  # where the run of one STX byte that `pos` lies in ends, once known
        while pos < end:
            b = buf[pos]
            if b != STX_V2 and b != STX_V1:
                nxt = _next_stx(buf, pos + 1, end)
                if skip_from < 0:
                    skip_from = pos
                pos = nxt
                continue
            cand = self.candidate(buf, pos, end)
            if cand is None and final:
                # One or two bytes left: too little to call a frame.
                if skip_from < 0:
                    skip_from = pos
                pos = end
                break
            if cand is None or cand[1] is TRUNCATED:
                if not final:
                    break  # wait for more bytes
                # The rest of the data is shorter than this frame: a real truncated frame, unless a
                # valid frame starts later (then this STX was a stray byte).
                if not valid_from <= pos + 1 <= valid_at:
                    valid_from = pos + 1
                    valid_at = _next_stx(buf, pos + 1, end)
                    while valid_at < end and _check_at(buf, valid_at, end, messages) != VALID:
                        valid_at = _next_stx(buf, valid_at + 1, end)
                later = valid_at
                if later < end:
                    if skip_from < 0:
                        skip_from = pos
                    pos = later
                    continue
                if skip_from >= 0:
                    skipped.append((skip_from, pos - skip_from))
                    skip_from = -1
                frames.append((pos, end - pos, TRUNCATED, None))
                pos = end
                break
            size, status, crc = cand
            if status is not OK:
                after = pos + size
                verdict = _check_at(buf, after, end, messages) if after < end else VALID
                if verdict == NEED_MORE and not final:
                    break  # not enough lookahead to tell a damaged frame from a stray STX: wait
                if verdict != VALID:
                    if skip_from < 0:
                        skip_from = pos
                    if pos + 1 < end and buf[pos + 1] == b:  # in a run of one STX byte
                        if pos >= run_to:
                            run_to = _RUNS[b](buf, pos, end).end()  # type: ignore[union-attr]  # matches at pos
                        # Every start up to run_to - 2 * size sees the same bytes as this one (the frame
                        # and the one after it inside the run): the same verdict, skipped at once.
                        pos = max(pos + 1, run_to - 2 * size + 1)
                    else:
                        pos = _next_stx(buf, pos + 1, end)
                    continue
                if after == end and not final:
                    break  # a stream may still bring the proof (or the refutation)
            if skip_from >= 0:
                if status is OK and _cut_short(buf, skip_from, pos, messages):
                    frames.append((skip_from, pos - skip_from, TRUNCATED, None))
                else:
                    skipped.append((skip_from, pos - skip_from))
                skip_from = -1
            frames.append((pos, size, status, crc))
            pos += size
        if skip_from >= 0:
            skipped.append((skip_from, min(pos, end) - skip_from))
        return frames, skipped, min(pos, end)


def build_frame(
    buf: bytes,
    pos: int,
    size: int,
    status: CrcStatus,
    crc: int | None,
    messages: dict[int, MessageDef],
    record: int,
    index: int,
    time: float | None,
    transport: str,
    src: Endpoint | None,
    dst: Endpoint | None,
    offset: int | None,
    notes: tuple[Note, ...],
    span: tuple[int, ...] | None,
) -> Frame:
    """Make a Frame from a scanned candidate (header fields parsed, payload left for later)."""
    raw = buf[pos : pos + size]
    if raw[0] == STX_V2 and size >= HEADER_V2:
        _, length, iflags, cflags, seq, sysid, compid, lo, hi = unpack_v2(raw)
        msgid = lo | (hi << 16)
        sig = None
        if iflags & IFLAG_SIGNED and status is not TRUNCATED:
            link_id, ts, value = unpack_signature(raw, size - SIGNATURE_LEN)
            sig = Signature(link_id, int.from_bytes(ts, "little"), value)
        version = 2
    elif raw[0] == STX_V1 and size >= HEADER_V1:
        _, length, seq, sysid, compid, msgid = _V1(raw)
        iflags = cflags = 0
        sig = None
        version = 1
    else:  # a truncated header: report what is there
        version = 2 if raw[0] == STX_V2 else 1
        hdr = raw + bytes((HEADER_V2 if version == 2 else HEADER_V1) - len(raw))
        if version == 2:
            _, length, iflags, cflags, seq, sysid, compid, lo, hi = unpack_v2(hdr)
            msgid = lo | (hi << 16)
        else:
            _, length, seq, sysid, compid, msgid = _V1(hdr)
            iflags = cflags = 0
        sig = None
    md = messages.get(msgid)
    extra: list[Note] = []
    if status is TRUNCATED:
        extra.append(note("truncated-frame", f"frame truncated: {size} of {announced_size(raw)} bytes present", offset))
    elif status is BAD:
        extra.append(bad_crc_note(f"{crc:04x}", offset))
    elif status is UNCHECKED:
        extra.append(note("unknown-msgid", f"message id {msgid} is not in the loaded dialects: CRC unchecked", offset))
    if iflags & ~KNOWN_IFLAGS:
        if iflags & IFLAG_ENCRYPTION_MASK:
            extra.append(
                note("encrypted-payload", f"payload encrypted with method {(iflags & IFLAG_ENCRYPTION_MASK) >> 5} "
                     "(incompat flag bits 5-7)", offset)
            )
        if iflags & ~(KNOWN_IFLAGS | IFLAG_ENCRYPTION_MASK):
            extra.append(note("unknown-incompat-flags", f"unknown incompat flags 0x{iflags:02x}", offset))
    if md is not None and status is not TRUNCATED:
        if version == 1 and length != md.base_length:
            extra.append(note("length-mismatch", f"v1 payload of {length} bytes, {md.name} has {md.base_length}",
                              offset))
        elif length > md.length and not iflags & IFLAG_ENCRYPTION_MASK:
            extra.append(note("length-mismatch", f"payload of {length} bytes, {md.name} has {md.length}", offset))
        if md.chars and not iflags & ~KNOWN_IFLAGS:  # (a payload that is decoded)
            hlen = HEADER_V2 if version == 2 else HEADER_V1
            extra.extend(char_notes(md, raw[hlen : hlen + min(length, md.length)], offset))
    if extra:
        notes = notes + tuple(extra)
    return new_frame(record, index, time, transport, src, dst, offset, raw, version, length, iflags, cflags, seq,
                     sysid, compid, msgid, crc, status, md, sig, notes, span)


def bad_crc_note(crc_hex: str, offset: int | None) -> Note:
    """The note of a frame whose CRC (as sent, 4 hex digits) does not match; the native walker writes it from
    a template made of this one (mavscope.native.walk.note_templates)."""
    return note("bad-crc", f"CRC 0x{crc_hex} does not match the frame", offset)


def with_bad_crc(frame: Frame) -> Frame:
    """`frame`, whole and otherwise clean, as `build_frame` gives it when its CRC does not match (the native
    walker's column mode gives such a frame as a code: mavscope.native.windows.noted)."""
    return frame._replace(crc_status=BAD, notes=(*frame.notes, bad_crc_note(f"{frame.crc:04x}", frame.offset)))


def char_notes(md: MessageDef, payload: bytes, offset: int | None) -> list[Note]:
    """`char-after-nul` for each char array of `payload` (a plaintext payload of message `md`) that holds
    bytes after the NUL ending its string: the field and the count, for what no reader of the value sees."""
    out = []
    for fd in md.chars:
        tail = char_tail(payload[fd.offset : fd.offset + fd.size])
        if tail:
            out.append(note("char-after-nul", f"{md.name}.{fd.name}: {tail} byte{'s' if tail > 1 else ''} after the "
                            "NUL that ends the string (not part of its value)", offset))
    return out


def has_char_tail(md: MessageDef, data: bytes, start: int, end: int) -> bool:
    """Whether a char array of message `md`, whose payload is data[start:end], holds bytes after the NUL
    that ends its string (the test of `char_notes`, without copying the payload)."""
    for fd in md.chars:
        a = start + fd.offset
        b = min(a + fd.size, end)
        z = data.find(0, a, b)
        if 0 <= z and data.count(0, z, b) != b - z:
            return True
    return False


def announced_size(raw: bytes) -> int:
    """The full size a (possibly truncated) frame announces, or its header size if LEN is missing."""
    if len(raw) >= 3:
        return frame_size(raw, 0)
    return HEADER_V2 if raw[0] == STX_V2 else HEADER_V1


def skipped_note(count: int, offset: int | None) -> Note:
    where = f" at offset {offset}" if offset is not None else ""
    return note("skipped-bytes", f"{count} bytes that are not MAVLink skipped{where}", offset)


class StreamFramer:
    """Frames of one byte stream (a TCP direction, a raw file), fed in order, possibly in pieces."""

    __slots__ = ("framer", "buf", "start", "segs", "trusted", "key", "pending", "walking", "shown", "claimed")

    def __init__(self, framer: Framer, key: Hashable) -> None:
        self.framer = framer
        self.key = key
        self.buf = b""
        self.start = 0  # where in buf the framer goes on (the bytes before it are kept for `walking`)
        # (start position in buf, record number, file offset of that position or None, record and time at
        # which the piece became readable)
        self.segs: list[tuple[int, int, int | None, Ready]] = []
        self.trusted = False
        self.pending: list[Note] = []
        # MAVLink's C library's receivers out of step with the framer where the framer stopped, to go on
        # with the next piece (mavscope.mavlink.hidden); the framer's frames and the hidden frames already
        # given in the bytes kept for them
        self.walking: dict[Receiver, Walking] = {}
        self.shown: list[Scanned] = []
        self.claimed: list[int] = []

    def _locate(self, pos: int) -> tuple[int, int | None]:
        """Record and file offset of buffer position `pos`."""
        rec, off = self.segs[0][1], None
        for start, r, o, _ in self.segs:
            if start > pos:
                break
            rec = r
            off = None if o is None else o + (pos - start)
        return rec, off

    def feed(self, data: bytes, record: int, offset: int | None, notes: tuple[Note, ...] = (),
             ready: Ready = (0, None)) -> None:
        """Append the next in-order bytes of the stream (`ready`: the record, and its capture time, at which
        they became readable in order; a frame they complete is dated by it)."""
        if notes:
            self.pending.extend(notes)
        if not data:
            return
        self.segs.append((len(self.buf), record, offset, ready))
        self.buf = self.buf + data if self.buf else data

    def take(self, final: bool) -> tuple[list[StreamPiece], list[Note]]:
        """Frames now complete, as (buf, pos, size, status, crc, offset, span, notes), and orphan notes.

        With `final` the stream has ended: everything left is decided.
        """
        buf = self.buf
        if not buf:
            orphans: list[Note] = self.pending if final else []
            if final:
                self.pending = []
            return [], orphans
        found, skipped, resume = self.framer.scan(buf, self.start, len(buf), final)
        hidden, walking = hidden_frames(self.framer.candidate, buf, found, skipped, resume, len(buf), final,
                                        self.walking, self.shown, self.claimed)
        out = []
        orphans = []
        sk = 0
        segs = self.segs
        last = len(segs) - 1
        i = 0  # the piece holding the frame's first byte (frames come by position: it only moves on)
        for (pos, size, status, crc), h in merged(found, hidden):
            if status is OK:
                self.trusted = True
            while sk < len(skipped) and skipped[sk][0] < pos:
                s_pos, s_count = skipped[sk]
                sk += 1
                self.pending.append(skipped_note(s_count, self._locate(s_pos)[1]))
            while i < last and segs[i + 1][0] <= pos:
                i += 1
            start, first_rec, o, done = segs[i]
            off = None if o is None else o + (pos - start)
            j, end = i, pos + size
            while j < last and segs[j + 1][0] < end:  # the piece holding its last byte
                j += 1
            if j == i:  # (most frames: one piece, one record)
                span: tuple[int, ...] = (first_rec,)
            else:  # the records holding its bytes, in record order; dated by the piece of its last byte
                span = tuple(sorted({seg[1] for seg in segs[i:j + 1]}))
                done = segs[j][3]
            if h is not None:
                self.pending.append(hidden_note(h, off))
            notes = tuple(self.pending)
            self.pending = []
            out.append((buf, pos, size, status, crc, off, span, notes, done))
        for s_pos, s_count in skipped[sk:]:
            if self.trusted:
                self.pending.append(skipped_note(s_count, self._locate(s_pos)[1]))
        if not self.trusted:
            # Not (yet) known to be MAVLink: a stream of something else is not reported at all.
            out = [o for o in out if o[3] is OK]
        # Keep the bytes from where the framer goes on, or from where a receiver out of step reads on
        # (a frame it is in, at most a frame's worth before): the next piece's walk starts there
        self.walking = {} if final else walking
        keep = min([resume, *(w[0] for w in self.walking.values())])
        self.start = resume - keep
        if self.walking:
            self.shown = [(f[0] - keep, *f[1:]) for f in (*self.shown, *found) if f[0] >= keep]
            self.claimed = [h[0][0] - keep for h in hidden if h[0][0] >= keep] + [c - keep for c in self.claimed
                                                                                   if c >= keep]
            self.walking = {r: (w[0] - keep, w[1] - keep, w[2]) for r, w in self.walking.items()}
        else:
            self.shown, self.claimed = [], []
        if keep >= len(buf):
            self.buf = b""
            self.segs = []
        else:
            self.buf = buf[keep:]
            segs = []
            for start, r, o, ready in self.segs:
                if start <= keep:
                    segs = [(0, r, None if o is None else o + (keep - start), ready)]
                else:
                    segs.append((start - keep, r, o, ready))
            self.segs = segs
        if final:
            orphans, self.pending = self.pending, []
        return out, orphans
