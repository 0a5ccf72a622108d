"""Raw byte streams (a serial dump, a socket recording): the file in consecutive chunks."""

from __future__ import annotations

import os
from collections.abc import Iterator

from mavscope.capture.base import LINKTYPE_MAVLINK_RAW, Record
from mavscope.capture.reader import CaptureReader, make_record

CHUNK = 65536


class RawReader(CaptureReader):
    """Yields the file as 64 KiB chunks without timestamps; MAVLink frames may span chunks."""

    kind = "raw"

    def __init__(self, path: str | os.PathLike[str], chunk: int = CHUNK) -> None:
        super().__init__(path)
        self._linktype = LINKTYPE_MAVLINK_RAW
        self.chunk = chunk

    def _records(self) -> Iterator[Record]:
        buf, size, chunk = self._buf, self.size, self.chunk
        n = 0
        for pos in range(0, size, chunk):
            data = buf[pos:pos + chunk]
            n += 1
            self.position = pos + len(data)
            yield make_record(n, None, LINKTYPE_MAVLINK_RAW, data, pos, len(data))
