"""The bytes of one object as they arrive: placed by offset, first copy kept, the holes remembered.

A transfer carries its file in pieces that may come out of order, twice (a retried burst, a retried
write) or never (a lost packet). `Content` keeps one `bytearray` per object, grown to the end of the
furthest piece, and the received ranges as sorted, merged intervals. A piece over bytes already held is
compared with them: equal bytes count as duplicates, different ones as conflicts (the first copy stays,
as MAVProxy's and pymavlink's FTP clients ignore data they already hold). What was never received is a
gap; the written file holds zeros there.

Memory is bounded: every buffer is charged to a `Budget` shared by all objects of a capture, a piece
beyond `max_object` bytes from the start of its object is cut, and an object fragmented into more than
`max_ranges` pieces takes no new piece. So is the work a frame can cause: a piece placed past the end of
the buffer leaves a hole of zeros before it, which would otherwise cost up to `max_object` bytes of
memory, hashing and disk for a frame of a few hundred bytes. Holes are charged to the budget's `holes`
allowance, shared by the capture's objects and given back only when data fills them; a piece whose hole
the allowance cannot pay for is not kept. What a limit cut is counted (`dropped`) and said (`problems`).
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right


class Budget:
    """Bytes held by every object's buffer, at most `limit`; bytes of holes (never received, held as zeros)
    made by all objects together, at most `holes`."""

    __slots__ = ("limit", "held", "refused", "holes", "zeros")

    def __init__(self, limit: int, holes: int) -> None:
        self.limit = limit
        self.held = 0
        self.refused = 0  # bytes of data not kept because the budget was spent
        self.holes = holes
        self.zeros = 0  # bytes of holes charged and not filled since

    def hole(self, n: int) -> bool:
        """Charge a hole of `n` bytes; False (nothing charged) when the allowance cannot pay for it."""
        if self.zeros + n > self.holes:
            return False
        self.zeros += n
        return True

    def filled(self, n: int) -> None:
        """`n` bytes of holes were filled by data."""
        self.zeros = max(0, self.zeros - n)

    def take(self, n: int) -> bool:
        if self.held + n > self.limit:
            return False
        self.held += n
        return True

    def give(self, n: int) -> None:
        self.held = max(0, self.held - n)


class Content:
    """One object's bytes: a buffer, the received intervals, and what overlapped or was cut."""

    __slots__ = ("buf", "starts", "ends", "budget", "max_object", "max_ranges", "duplicates", "conflicts",
                 "dropped", "problems", "released")

    def __init__(self, budget: Budget, max_object: int, max_ranges: int) -> None:
        self.buf = bytearray()
        self.starts: list[int] = []
        self.ends: list[int] = []
        self.budget = budget
        self.max_object = max_object
        self.max_ranges = max_ranges
        self.duplicates = 0  # bytes received again with the same value
        self.conflicts = 0  # bytes received again with another value (the first copy is kept)
        self.dropped = 0  # bytes not kept: beyond the object limit, the memory budget or the range limit
        self.problems: set[str] = set()
        self.released = False

    @property
    def end(self) -> int:
        """One past the last byte received (0 when nothing was)."""
        return self.ends[-1] if self.ends else 0

    @property
    def received(self) -> int:
        """Distinct bytes received."""
        return sum(e - s for s, e in zip(self.starts, self.ends, strict=True))

    def add(self, offset: int, data: bytes) -> int:
        """Place `data` at `offset`; returns how many of its bytes were new."""
        if not data or self.released:
            return 0
        end = offset + len(data)
        if end > self.max_object:
            keep = max(0, self.max_object - offset)
            self.dropped += len(data) - keep
            self.problems.add(f"data beyond the {self.max_object:,}-byte object limit was not kept")
            data = data[:keep]
            end = offset + keep
            if not data:
                return 0
        lo = bisect_left(self.ends, offset)  # the first interval ending at or after the piece's start
        hi = bisect_right(self.starts, end)  # past the last interval starting at or before its end
        if lo == hi and len(self.starts) >= self.max_ranges:
            self.dropped += len(data)
            self.problems.add(f"more than {self.max_ranges:,} separate pieces: later pieces were not kept")
            return 0
        length = len(self.buf)
        if end > length:
            grow = end - length
            if not self.budget.take(grow):
                self.dropped += len(data)
                self.budget.refused += len(data)
                self.problems.add("the memory limit for objects was reached: later data was not kept")
                return 0
            if offset > length and not self.budget.hole(offset - length):
                self.budget.give(grow)
                self.dropped += len(data)
                self.problems.add(f"the limit of {self.budget.holes:,} bytes of holes (data never received) was "
                                  "reached: pieces past a hole were not kept")
                return 0
            self.buf.extend(bytes(grow))
        new = 0
        pos = offset
        for k in range(lo, hi):
            s, e = self.starts[k], self.ends[k]
            if s > pos:  # a hole before this interval: new bytes
                self.buf[pos:s] = data[pos - offset : s - offset]
                new += s - pos
            a, b = max(s, offset), min(e, end)
            if a < b:
                held = self.buf[a:b]
                piece = data[a - offset : b - offset]
                if held == piece:
                    self.duplicates += b - a
                else:
                    differ = sum(1 for x, y in zip(held, piece, strict=True) if x != y)
                    self.conflicts += differ
                    self.duplicates += (b - a) - differ
            pos = max(pos, e)
        if pos < end:
            self.buf[pos:end] = data[pos - offset :]
            new += end - pos
        if offset < length:  # the new bytes below the buffer's old end filled holes
            self.budget.filled(new - max(0, end - max(length, offset)))
        if lo < hi:
            start, stop = min(offset, self.starts[lo]), max(end, self.ends[hi - 1])
        else:
            start, stop = offset, end
        self.starts[lo:hi] = [start]
        self.ends[lo:hi] = [stop]
        return new

    def gaps(self, size: int) -> list[tuple[int, int]]:
        """The ranges of [0, size) never received, as [start, end) pairs."""
        return holes(self.starts, self.ends, size)

    def covered(self, start: int, stop: int) -> bool:
        """Whether every byte of [start, stop) was received."""
        k = bisect_right(self.starts, start) - 1
        return start >= stop or (k >= 0 and self.ends[k] >= stop)

    def data(self, size: int) -> bytes:
        """The object's bytes, zero-filled where nothing was received, cut or padded to `size`."""
        out = bytes(self.buf[:size])
        return out + bytes(size - len(out)) if len(out) < size else out

    def release(self) -> None:
        """Give the buffer back to the budget (the object is finished)."""
        if not self.released:
            self.budget.give(len(self.buf))
            self.buf = bytearray()
            self.released = True


class Ranges:
    """Sorted, merged [start, end) intervals without data (the bytes of an upload the server acknowledged)."""

    __slots__ = ("starts", "ends", "limit")

    def __init__(self, limit: int) -> None:
        self.starts: list[int] = []
        self.ends: list[int] = []
        self.limit = limit

    def add(self, start: int, stop: int) -> None:
        if stop <= start:
            return
        lo = bisect_left(self.ends, start)
        hi = bisect_right(self.starts, stop)
        if lo == hi and len(self.starts) >= self.limit:
            return
        if lo < hi:
            start, stop = min(start, self.starts[lo]), max(stop, self.ends[hi - 1])
        self.starts[lo:hi] = [start]
        self.ends[lo:hi] = [stop]

    def missing(self, size: int) -> list[tuple[int, int]]:
        """The ranges of [0, size) not in the intervals."""
        return holes(self.starts, self.ends, size)


def holes(starts: list[int], ends: list[int], size: int) -> list[tuple[int, int]]:
    """The ranges of [0, size) outside the sorted, merged intervals (starts[i], ends[i])."""
    out = []
    pos = 0
    for s, e in zip(starts, ends, strict=True):
        if s >= size:
            break
        if s > pos:
            out.append((pos, s))
        pos = max(pos, e)
    if pos < size:
        out.append((pos, size))
    return out
