"""Raw byte streams (a serial dump, a socket recording): the file in consecutive chunks."""

from __future__ import annotations

import os
from collections.abc import Iterator

from mavscope.capture.base import LINKTYPE_MAVLINK_RAW, Record
from mavscope.capture.reader import READER_BUGS, CaptureReader, make_record

CHUNK = 65536


class RawReader(CaptureReader):
    """Yields the file as 64 KiB chunks without timestamps; MAVLink frames may span chunks."""

    kind = "raw"

    def __init__(self, path: str | os.PathLike[str], chunk: int = CHUNK) -> None:
        super().__init__(path)
        self._linktype = LINKTYPE_MAVLINK_RAW
        self.chunk = chunk

    def _records(self) -> Iterator[Record]:
        chunk = self.chunk
        n = 0
        pos = 0
        try:
            while pos < self.size:
                data = self.read_at(pos, chunk)
                if not data:
                    break
                n += 1
                self.position = pos + len(data)
                yield make_record(n, None, LINKTYPE_MAVLINK_RAW, data, pos, len(data))
                pos += len(data)
            shrunk = self.shrink_notes()
            if shrunk:
                n += 1
                yield make_record(n, None, LINKTYPE_MAVLINK_RAW, b"", pos, 0, shrunk)
        except READER_BUGS as exc:
            yield self.failure(n + 1, pos, exc)
