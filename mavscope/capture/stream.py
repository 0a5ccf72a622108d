"""A capture read from a pipe (`mavscope read -`): standard input as the readers' random access, in bounded memory.

The readers read a file by offset (`CaptureReader.read_at`), forward in windows, and take a short read for
the end of the file. `StreamBytes` gives them a pipe the same way: it reads the stream as far as a request
needs (blocking until the bytes are there or the stream ends) and keeps only the last KEEP bytes before the
latest request, so memory stays bounded however long the stream runs (`tcpdump -w - | mavscope read -`).
A request behind what it keeps is refused (CaptureError): no reader goes that far back. Its readers take
windows of STREAM_WINDOW bytes, so frames are shown about that many bytes after they arrive.
"""

from __future__ import annotations

from typing import BinaryIO

from mavscope.errors import CaptureError

STDIN = "-"  # the name that means standard input, as tshark's -r -
KEEP = 1 << 22  # bytes kept before the latest request
STREAM_WINDOW = 1 << 16  # a stream reader's window (a file reader's is 1 MiB)
UNKNOWN_SIZE = 1 << 62  # a stream's size until it ends


class StreamBytes:
    """The bytes of a forward-only stream by offset (see the module docstring)."""

    def __init__(self, f: BinaryIO) -> None:
        self._f = f  # a buffered reader: read(n) gives n bytes, or fewer only at the end
        self.base = 0  # the offset of buf[0]
        self.buf = bytearray()
        self.ended = False

    def read_at(self, offset: int, n: int) -> bytes:
        """Up to `n` bytes from `offset`: fewer only where the stream ended."""
        if offset < self.base:
            raise CaptureError(f"a reader went back to offset {offset} of standard input, which keeps only from "
                               f"offset {self.base} on", path=STDIN)
        end = offset + n
        while self.base + len(self.buf) < end and not self.ended:
            chunk = self._f.read(end - self.base - len(self.buf))
            if not chunk:
                self.ended = True
                break
            self.buf += chunk
        drop = offset - KEEP - self.base
        if drop > 0:
            del self.buf[:drop]
            self.base += drop
        rel = offset - self.base
        return bytes(self.buf[rel:rel + n])
