"""STATUSTEXT as a ground station shows it: the chunks of a long text joined into one message.

A text longer than STATUSTEXT's 50 bytes is sent in chunks (common.xml, MAVLink 2 extension fields):
`id`, "unique (opaque) identifier for this statustext message ... A value of zero indicates this is the
only chunk", and `chunk_seq`, "this chunk's sequence number; indexing is from zero. Any null character in
the text field is taken to mean this was the last chunk". They are joined as QGroundControl joins them
(mavlink/qgroundcontrol, src/MAVLink/StatusTextHandler.cc `_handleStatusText`,
`_chunkedStatusTextTimeout` and `_chunkedStatusTextCompleted`; before 2024 the same code in
src/Vehicle/Vehicle.cc with `_chunkedStatusTextInfoMap`):

- one text in progress per sender (QGroundControl keeps one per component of each vehicle);
- a text with id 0 is whole: shown at once;
- a chunk with another id than the text in progress ends that text first, its end marked missing;
- a chunk numbered past the next one marks the chunks between as missing;
- a chunk whose 50 bytes hold a NUL is the last: the text is complete;
- a text that gets no chunk for TIMEOUT seconds ends, its end marked missing (QGroundControl's single-shot
  timer of 1000 ms, restarted by every chunk); so does one the capture ends in.

QGroundControl shows a missing chunk as " ... ". mavscope says which: `[chunk 2 missing]`, and
`[end not seen]` for a text whose last chunk never came; the JSON lists the missing chunk numbers. Where
mavscope differs from QGroundControl, it is to say more or to keep a sender's bytes apart: chunks missing
before the first one seen are marked too (QGroundControl starts from whatever chunk comes first); a chunk
repeating one held with the same bytes (one frame seen on two links) is a copy, not added twice
(QGroundControl appends it again); a chunk with the number of one held but other bytes ends the text and
starts another; the timeout runs per sender (QGroundControl's one timer per vehicle is stopped by any text
that completes); the last chunk is told by a NUL among its bytes, as the XML says (QGroundControl counts
the decoded characters, so a chunk with a multi-byte UTF-8 character ends its text too early); and the
chunks are joined as bytes before they are decoded, so a character split over two chunks stays whole. A
chunk's text ends at its first NUL (`char_text`'s rule). At most MAX_OPEN texts are in progress at once
(one per sender): the sender heard from least recently ends first (`TextEnd.LIMIT`).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from enum import Enum

from mavscope.analysis.params.values import field_bytes
from mavscope.mavlink.frame import Addr, Frame

TIMEOUT = 1.0  # seconds without a chunk after which a text in progress ends (QGroundControl's 1000 ms)
MAX_OPEN = 256  # texts in progress at once (one per sender)

Fields = dict[str, object]


class TextEnd(str, Enum):
    """How a text ended."""

    WHOLE = "whole"  # id 0: one STATUSTEXT
    LAST = "last-chunk"  # its last chunk came (a NUL in the text)
    NEXT_ID = "next-id"  # the sender began another text
    TIMEOUT = "timeout"  # no chunk for TIMEOUT seconds
    CONFLICT = "conflict"  # a chunk came again with other bytes (it begins another text)
    CAPTURE_END = "capture-end"
    LIMIT = "limit"  # MAX_OPEN texts in progress: the least recent sender's ended


COMPLETE = frozenset({TextEnd.WHOLE, TextEnd.LAST})


@dataclass(frozen=True, slots=True)
class StatusText:
    """One message as a ground station shows it, from one STATUSTEXT or the chunks of one text."""

    sender: Addr
    severity: int  # the first chunk's (as QGroundControl takes it)
    ident: int  # STATUSTEXT.id (0: not chunked)
    chunks: tuple[bytes | None, ...]  # by chunk_seq: the chunk's text (up to its NUL), None for a missing one
    frames: tuple[int, ...]  # the records of the chunks, in capture order
    time: float | None  # the first chunk's capture time
    frame: int  # the first chunk's record
    end: TextEnd

    @property
    def missing(self) -> tuple[int, ...]:
        """The numbers of the chunks missing before the last one seen."""
        return tuple(k for k, c in enumerate(self.chunks) if c is None)

    @property
    def complete(self) -> bool:
        """Every chunk up to the last one came."""
        return self.end in COMPLETE and None not in self.chunks

    @property
    def text(self) -> str:
        """The joined text: runs of chunks decoded as UTF-8 (undecodable bytes as \\xNN escapes), missing
        chunks and a missing end said in brackets."""
        parts: list[str] = []
        run: list[bytes] = []
        k = 0
        chunks = self.chunks
        while k < len(chunks):
            c = chunks[k]
            if c is not None:
                run.append(c)
                k += 1
                continue
            if run:
                parts.append(b"".join(run).decode("utf-8", "backslashreplace"))
                run = []
            j = k
            while j + 1 < len(chunks) and chunks[j + 1] is None:
                j += 1
            parts.append(f"[chunk {k} missing]" if j == k else f"[chunks {k}-{j} missing]")
            k = j + 1
        if run:
            parts.append(b"".join(run).decode("utf-8", "backslashreplace"))
        if self.end not in COMPLETE:
            parts.append("[end not seen]")
        return "".join(parts)


@dataclass(slots=True)
class _Open:
    """A text in progress."""

    ident: int
    severity: int
    time: float | None
    frame: int
    chunks: list[bytes | None]
    frames: list[int]
    last: float | None  # capture time of its latest chunk

    def done(self, sender: Addr, end: TextEnd) -> StatusText:
        return StatusText(sender, self.severity, self.ident, tuple(self.chunks), tuple(self.frames), self.time,
                          self.frame, end)


class StatusTextJoiner:
    """STATUSTEXT frames in capture order -> the messages they make (see the module docstring)."""

    def __init__(self, timeout: float = TIMEOUT, max_open: int = MAX_OPEN) -> None:
        self.timeout = timeout
        self.max_open = max_open
        self.open: OrderedDict[Addr, _Open] = OrderedDict()  # least recently added to first

    def add(self, f: Frame, fields: Fields) -> list[StatusText]:
        """The messages STATUSTEXT frame `f` (its decoded `fields`) ends: none, or the one in progress
        it ends and/or the one it completes."""
        raw = field_bytes(f, "text")
        severity, ident, seq = fields.get("severity"), fields.get("id", 0), fields.get("chunk_seq", 0)
        if raw is None or not isinstance(severity, int) or not isinstance(ident, int) or not isinstance(seq, int):
            return []
        nul = raw.find(0)
        text = raw if nul < 0 else raw[:nul]
        sender = (f.sysid, f.compid)
        out: list[StatusText] = []
        cur = self.open.get(sender)
        if cur is not None:
            late = f.time is not None and cur.last is not None and f.time - cur.last > self.timeout
            if late or cur.ident != ident:
                out.append(self._end(sender, TextEnd.TIMEOUT if late else TextEnd.NEXT_ID))
                cur = None
        if ident == 0:
            out.append(StatusText(sender, severity, 0, (text,), (f.record,), f.time, f.record, TextEnd.WHOLE))
            return out
        if cur is not None and seq < len(cur.chunks) and cur.chunks[seq] is not None:
            if cur.chunks[seq] == text:  # a copy of a chunk held
                cur.last = f.time if f.time is not None else cur.last
                return out
            out.append(self._end(sender, TextEnd.CONFLICT))
            cur = None
        if cur is None:
            cur = self.open[sender] = _Open(ident, severity, f.time, f.record, [], [], f.time)
            if len(self.open) > self.max_open:
                out.append(self._end(next(iter(self.open)), TextEnd.LIMIT))
        else:
            self.open.move_to_end(sender)
        if seq >= len(cur.chunks):
            cur.chunks.extend([None] * (seq - len(cur.chunks)))
            cur.chunks.append(text)
        else:
            cur.chunks[seq] = text  # one marked missing came late
        cur.frames.append(f.record)
        if f.time is not None:
            cur.last = f.time
        if nul >= 0:
            out.append(self._end(sender, TextEnd.LAST))
        return out

    def finish(self) -> list[StatusText]:
        """The texts the capture ends in."""
        return [self._end(sender, TextEnd.CAPTURE_END) for sender in list(self.open)]

    def _end(self, sender: Addr, end: TextEnd) -> StatusText:
        return self.open.pop(sender).done(sender, end)
