"""UDP receivers that keep their parser's state from one datagram to the next.

MAVLink's C library keeps one parser per link, and the receivers feed it every byte a UDP port gets, one
datagram after another: PX4's mavlink_receiver (recvfrom, then mavlink_parse_char over the bytes, one
status per instance), QGroundControl's UDPLink (MAVLinkProtocol::receiveBytes, one channel per link),
ArduPilot's GCS_MAVLINK (its UDP ports are byte streams to the parser, as its serial ports are), and
pymavlink's mavudp (one buffer across recv calls). So a frame split over two datagrams to the same
destination is read whole, where mavscope's framer, pymavlink's per-datagram decoding and Wireshark see a
frame cut short at the end of one datagram and bytes that are not MAVLink at the start of the next.
Serial-to-UDP bridges that send whatever bytes they have (socat, ser2net) split frames so; an attacker
can too, to hide a command from per-datagram tools.

`across` walks a datagram as such a receiver: it goes on with what the last datagram to the same
destination left (`Waiting`: the bytes from the frame the receiver is in, where each entry point is),
with the walks of mavscope.mavlink.hidden, which say where the receiver is at the datagram's end. A
datagram whose receivers are idle at its end (every clean datagram) leaves nothing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from mavscope.mavlink.hidden import ACROSS, Candidate, Hidden, Receiver, Scanned, Walking, hidden_frames
from mavscope.notes import Note, note

MAX_WAITING = 256  # destinations whose receivers are in a frame at once; past that the oldest is let go


@dataclass(frozen=True, slots=True)
class Waiting:
    """What a datagram left its destination's receivers in the middle of: the bytes from the earliest frame
    one of them is in (`tail`), where each is in them, the framer's frames and the hidden frames already
    shown there, and where the bytes came from: (position in tail, record, file offset or None), by
    position."""

    tail: bytes
    walking: Mapping[Receiver, Walking]
    shown: tuple[Scanned, ...]
    claimed: tuple[int, ...]
    segs: tuple[tuple[int, int, int | None], ...]

    def locate(self, pos: int) -> tuple[int | None, tuple[int, ...]]:
        """The file offset of tail position `pos` and the records its bytes from there came in."""
        i = max(j for j, seg in enumerate(self.segs) if seg[0] <= pos)  # segs[0] starts at 0
        start, _, off = self.segs[i]
        return None if off is None else off + pos - start, tuple(seg[1] for seg in self.segs[i:])


def across(candidate: Candidate, data: bytes, found: Sequence[Scanned], skipped: Sequence[tuple[int, int]],
           waiting: Waiting | None, record: int, offset: int | None) -> tuple[bytes, int, list[Hidden], Waiting | None]:
    """The hidden frames of datagram `data` (record `record` at file offset `offset`, the framer's view
    `found` and `skipped`) for receivers that go on from `waiting`, and what it leaves them in.

    Returns the bytes walked (the waiting tail, then data), where data starts in them, the hidden frames
    by position in them (a frame before that start began in an earlier datagram), and the Waiting for
    the next datagram to the same destination (None: its receivers are idle at this one's end)."""
    t = 0
    if waiting is None:
        buf = data
        hidden, left = hidden_frames(candidate, data, found, skipped, len(data), len(data))
    else:
        t = len(waiting.tail)
        buf = waiting.tail + data
        found = [(f[0] + t, *f[1:]) for f in found]
        skipped = [(s + t, c) for s, c in skipped]
        hidden, left = hidden_frames(candidate, buf, found, skipped, len(buf), len(buf), True, waiting.walking,
                                     waiting.shown, waiting.claimed)
    if not left:
        return buf, t, hidden, None
    keep = min(w[0] for w in left.values())
    # the frame the receiver is in is the one it parted at: a frame this datagram's end cut short
    walking = {r: (p - keep, at - keep, ACROSS if how is None and at == p else how) for r, (p, at, how) in left.items()}
    segs = [(0, record, offset)] if waiting is None else [*waiting.segs, (t, record, offset)]
    kept: list[tuple[int, int, int | None]] = []
    for start, r, o in segs:
        if start <= keep:
            kept = [(0, r, None if o is None else o + (keep - start))]
        else:
            kept.append((start - keep, r, o))
    shown = tuple((f[0] - keep, *f[1:]) for f in (*(waiting.shown if waiting else ()), *found) if f[0] >= keep)
    claimed = tuple(c - keep for c in (*(waiting.claimed if waiting else ()), *(h[0][0] for h in hidden)) if c >= keep)
    return buf, t, hidden, Waiting(buf[keep:], walking, shown, claimed, tuple(kept))


def split_note(h: Hidden, before: int, records: tuple[int, ...], offset: int | None) -> Note:
    """The note on hidden frame `h`, whose first `before` bytes came in the datagrams of `records`, at
    file offset `offset`."""
    (_, size, _, _), _, _, receivers = h
    who = "MAVLink's C library (ArduPilot, PX4, QGroundControl)" if len(receivers) == len(Receiver) else (
        " and ".join(r.value for r in receivers))
    return note("split-frame", f"{who}, reading the datagrams to this destination as one run of bytes, reads "
                f"this frame: its first {before} of {size} bytes came in record {', '.join(map(str, records))}, "
                "the rest in this datagram, where per-datagram readers (pymavlink's decoding of a capture, "
                "Wireshark, mavscope's framer) see a frame cut short and bytes that are not MAVLink", offset)
