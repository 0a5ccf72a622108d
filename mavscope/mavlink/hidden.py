"""Frames MAVLink's C library reads where the framer shows other bytes: what the framer's view would hide.

The framer reads a frame by its LEN byte and resynchronises byte by byte after damage. MAVLink's C library
(mavlink_helpers.h) reads byte by byte and takes other turns:
- it drops a v2 frame at its INCOMPAT_FLAGS byte when a flag other than SIGNED is set (MAVLINK_IFLAG_MASK),
  and looks for an STX from the next byte on, inside what the framer shows as that frame (pymavlink and
  Wireshark skip the frame whole);
- it reads any other frame to its end, CRC good or bad (an unknown message id counts as bad), where the
  framer may have found a frame that started inside it, or shown it cut short by one.
Two entry points end a bad frame differently, and receivers use both:
- `mavlink_parse_char` (PX4, QGroundControl, MAVSDK) stops at the CRC, so a signed bad frame's signature
  bytes are read afresh, and starts a frame at its last byte when that byte is 0xFD;
- `mavlink_frame_char_buffer` (ArduPilot's GCS_MAVLINK) reads a signed bad frame's signature too, and
  starts afresh after it.
So a frame the vehicle reads and acts on can lie inside bytes the framer shows as another frame or as
skipped bytes. `hidden_frames` walks a datagram as each entry point does from each place where its view and
the framer's part, until they meet again, and returns the CRC-valid frames either reads that the framer
does not have. The datagram ends a walk: a receiver that starts each datagram afresh (tests/support/
cparser.py runs the C library so) reads nothing more. A stream (TCP, a serial dump) comes in pieces, and
the framer decides its bytes up to a point each time it is given more. A walk that needs bytes past that
point stops there and hands back where the receiver is (`Walking`); the next piece's walk goes on from it,
over the bytes the stream keeps for it (at most a frame's worth before the framer's point) and the frames
it showed there before (`shown`, `claimed`). A walk starts where the one before it met the framer again or
later, and a carried walk goes on where it stopped, so each position is walked once per entry point: the
work is linear in the size.
"""

from __future__ import annotations

import re
from bisect import bisect_left
from collections.abc import Callable, Collection, Mapping, Sequence
from enum import Enum

from mavscope.mavlink.frame import KNOWN_IFLAGS, CrcStatus
from mavscope.notes import Note, note
from mavscope.wire import HEADER_V1, HEADER_V2, STX_V2, frame_size

_STX = re.compile(b"[\xfd\xfe]")
OK, TRUNCATED = CrcStatus.OK, CrcStatus.TRUNCATED
Scanned = tuple[int, int, CrcStatus, "int | None"]  # (pos, size, status, crc), as Framer.scan gives them
# Framer.candidate: (size, CRC verdict, CRC) of the frame at pos in buf[:end]
Candidate = Callable[[bytes, int, int], "tuple[int, CrcStatus, int | None] | None"]


class Receiver(Enum):
    """MAVLink's C library's two entry points, named by the receivers that use them."""

    PARSE_CHAR = "PX4 and QGroundControl (mavlink_parse_char)"
    FRAME_CHAR = "ArduPilot (mavlink_frame_char_buffer)"


# A hidden frame: what Framer.scan gives for it; where the receiver last parted from the framer before
# reading it, and how (the incompat flags of the frame it dropped there, or None: it read a damaged frame
# there to its end); and the receivers that read it
Hidden = tuple[Scanned, int, "int | None", tuple[Receiver, ...]]
# A receiver out of step with the framer where the bytes so far end: where it reads on from (idle, or at the
# STX of the frame it is in), where it last parted from the framer, and how (as in Hidden)
Walking = tuple[int, int, "int | None"]
ACROSS = -1  # `how` where the receiver parted from the framer at a frame a datagram's end cut short (it reads
# that frame on into the next datagram to the same destination: mavscope.mavlink.receivers)


def dropped_by_receivers(buf: bytes, pos: int, size: int) -> bool:
    """Whether MAVLink's C library drops the frame at `pos` at its incompat flags byte."""
    return size >= 3 and buf[pos] == STX_V2 and bool(buf[pos + 2] & ~KNOWN_IFLAGS)


def _bad_end(buf: bytes, q: int, receiver: Receiver) -> int:
    """Where `receiver` is idle again after the bad frame at `q` (whole in the buffer)."""
    if receiver is Receiver.FRAME_CHAR:
        return q + frame_size(buf, q)
    v2 = buf[q] == STX_V2
    stop = q + (HEADER_V2 if v2 else HEADER_V1) + buf[q + 1] + 2  # the CRC ends it
    # The frame it starts at a last byte of 0xFD keeps the bad frame's layout: after a v1 frame, a v1
    # frame whose STX is 0xFD, which is no frame mavscope can show (a gap this model leaves)
    return stop - 1 if v2 and buf[stop - 1] == STX_V2 else stop


def _parts(buf: bytes, f: Scanned, end: int, receiver: Receiver) -> bool:
    """Whether `receiver` reads frame `f` of the framer otherwise than the framer shows it."""
    pos, size, status, _ = f
    if dropped_by_receivers(buf, pos, size):
        return True
    if status is TRUNCATED:  # cut short (by a frame after it, or by the end): the receiver reads on over
        return size >= 3  # what follows, or waits for the bytes that finish it
    return status is not OK and _bad_end(buf, pos, receiver) != pos + size


def _walk(candidate: Candidate, buf: bytes, starts: set[int], clean: set[int], origins: list[int], stx: list[int],
          limit: int, end: int, final: bool, receiver: Receiver, carried: Walking | None
          ) -> tuple[list[Hidden], Walking | None]:
    """The walks of one receiver: the one `carried` from the stream's last piece, then from `origins`
    (sorted), over the STX positions `stx` of buf[:limit]. With the receiver's state where the bytes did
    not decide it (None: in step with the framer at the end)."""
    out: list[Hidden] = []
    reach = 0  # where the walks so far met the framer again: the receiver is not idle at an origin before it
    walks: list[Walking] = [(o, o, None) for o in origins]
    if carried is not None:
        walks.insert(0, carried)
    for p, at, how in walks:
        if p < reach:
            continue
        while True:
            if p > limit and not final:  # past where the framer has decided, out of step: the next piece's
                return out, (p, at, how)
            i = bisect_left(stx, p)
            if i == len(stx):
                reach = limit  # idle up to where the framer has decided: in step there
                break
            q = stx[i]
            if q in clean:
                reach = q  # in step with the framer again
                break
            dropped = dropped_by_receivers(buf, q, end - q)
            if not dropped and (q + 3 > end or q + frame_size(buf, q) > end):
                # In the frame at q, waiting for bytes past the end: the stream's next piece brings them
                # (every origin left lies before that frame's end); a datagram's receiver reads no more
                return out, (q, at, how)
            if dropped:
                at, how = q, buf[q + 2]
                p = q + 3
                continue
            size, status, crc = candidate(buf, q, end)  # type: ignore[misc]  # whole: checked above
            if status is OK:
                if q not in starts:
                    out.append(((q, size, status, crc), at, how, (receiver,)))
                p = q + size
            else:
                at, how = q, None
                p = _bad_end(buf, q, receiver)
    return out, None


def hidden_frames(candidate: Candidate, buf: bytes, found: Sequence[Scanned], skipped: Sequence[tuple[int, int]],
                  limit: int, end: int, final: bool = True, carried: Mapping[Receiver, Walking] | None = None,
                  shown: Sequence[Scanned] = (), claimed: Collection[int] = ()
                  ) -> tuple[list[Hidden], dict[Receiver, Walking]]:
    """The frames MAVLink's C library reads that the framer's view (`found` and `skipped`, from Framer.scan
    over buf up to `limit`) does not have, by position, and the receivers whose state the bytes leave
    undecided (a walk needs bytes past `end`, or goes on past `limit` in a stream not `final`), with where
    each reads on. Each frame starts before `limit` and ends by `end` (a datagram: both its length; a
    stream has bytes past where the framer has decided).

    A stream's next piece passes what this one handed back as `carried`, with buf keeping the bytes from
    the earliest carried position on, the framer's frames shown before in those bytes (`shown`) and the
    positions of hidden frames given before (`claimed`). `candidate` is the Framer's, which judges a frame
    with its dialect's CRC_EXTRA."""
    # Only a frame the framer shows damaged, cut short or with unknown flags, or skipped bytes, can part
    # the two views: with none (nearly every datagram and stream piece that gets here) and no walk carried
    # over, there is nothing to walk.
    suspects = [f for f in found if f[2] is not OK or dropped_by_receivers(buf, f[0], f[1])]
    if not suspects and not skipped and not carried:
        return [], {}
    carried = carried or {}
    starts = {f[0] for f in found}
    starts.update(f[0] for f in shown)
    # a frame read where the framer shows it with a good CRC, or where one was given before, is not news (where
    # it shows a frame cut short by a datagram's end, a receiver reading on into the next one may read it whole)
    known = {f[0] for f in (*shown, *found) if f[2] is OK}
    known.update(claimed)
    by_receiver = {r: sorted([f[0] for f in suspects if _parts(buf, f, end, r)] + [s for s, _ in skipped])
                   for r in Receiver}
    first = min([o[0] for o in by_receiver.values() if o] + [w[0] for w in carried.values()], default=limit)
    stx = [m.start() for m in _STX.finditer(buf, first, limit)]
    by_pos: dict[int, Hidden] = {}
    undecided: dict[Receiver, Walking] = {}
    for receiver, origins in by_receiver.items():
        walking = carried.get(receiver)
        if not origins and walking is None:
            continue
        # where the receiver, idle, reads what the framer shows
        clean = starts.difference(origins, (f[0] for f in shown if _parts(buf, f, end, receiver)))
        hidden, left = _walk(candidate, buf, known, clean, origins, stx, limit, end, final, receiver, walking)
        if left is not None:
            undecided[receiver] = left
        for h in hidden:
            seen = by_pos.get(h[0][0])
            by_pos[h[0][0]] = h if seen is None else (*seen[:3], seen[3] + h[3])
    return sorted(by_pos.values()), undecided


def merged(found: Sequence[Scanned], hidden: Sequence[Hidden]) -> list[tuple[Scanned, Hidden | None]]:
    """The framer's frames (with None) and the hidden ones (with themselves), by position."""
    out: list[tuple[Scanned, Hidden | None]] = [(f, None) for f in found]
    if hidden:
        out.extend((h[0], h) for h in hidden)
        out.sort(key=lambda item: item[0][0])
    return out


def hidden_note(h: Hidden, offset: int | None) -> Note:
    """The note on hidden frame `h` (at file offset `offset`)."""
    (pos, _, _, _), at, iflags, receivers = h
    who = "MAVLink's C library (ArduPilot, PX4, QGroundControl)" if len(receivers) == len(Receiver) else (
        " and ".join(r.value for r in receivers))
    if iflags == ACROSS:
        how = (f"it reads the frame that began {pos - at} bytes before this one, in an earlier datagram to this "
               "destination, on into this one, and reads on from its end, where mavscope found other frames")
    elif iflags is not None:
        how = (f"it drops the frame {pos - at} bytes before this one at its incompat flags 0x{iflags:02x} and reads on "
               "from there, where pymavlink and Wireshark skip that frame whole")
    else:
        how = (f"it reads the damaged frame {pos - at} bytes before this one to its end, where mavscope found other "
               "frames")
    return note("hidden-frame", f"{who} reads this frame: {how}", offset)
