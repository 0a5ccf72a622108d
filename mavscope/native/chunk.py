"""One chunk of frames the C walker took in column mode (`_native.Columns.take`), as numpy views of its
buffers: the fixed-width columns (columns.h MS_COL_*, named by the module's COLUMN_NAMES), the wire bytes
and payloads with their offsets. The column-mode walk (native.windows), the export's Arrow columns
(native.columns) and its findings feed read it; the TUI's index reads its own subset (native.index).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


class Chunk:
    """One chunk of frames the C walker took, as numpy views of its buffers."""

    def __init__(self, n: int, columns: Sequence[Any], names: Sequence[str]) -> None:
        """`columns`: the chunk's `_native.Block`s (buffers), named by `names` (the module's COLUMN_NAMES)."""
        self.n = n
        self.blocks: dict[str, Any] = dict(zip(names, columns))
        b = self.blocks

        def view(name: str, dtype: str) -> np.ndarray:
            return np.frombuffer(b[name], np.dtype(dtype).newbyteorder("="), count=n)

        self.record = view("record", "i8")
        self.index = view("index", "i4")
        self.time = view("time", "f8")
        self.time_ok = view("time_ok", "u1").astype(np.bool_)
        self.transport = view("transport", "u1")
        self.src = view("src", "i4")
        self.dst = view("dst", "i4")
        self.version = view("version", "u1")
        self.len = view("len", "u1")
        self.iflags = view("incompat_flags", "u1")
        self.cflags = view("compat_flags", "u1")
        self.seq = view("seq", "u1")
        self.sysid = view("sysid", "u1")
        self.compid = view("compid", "u1")
        self.msgid = view("msgid", "u4")
        self.message = view("message", "i4")
        self.crc = view("crc", "u2")
        self.sig_link = view("signature_link_id", "u1")
        self.sig_time = view("signature_timestamp", "i8")
        self.sig_value = np.frombuffer(b["signature_value"], np.uint8, count=6 * n).reshape(n, 6)
        self.offset = view("offset", "i8")
        self.raw_at = np.frombuffer(b["raw_at"], np.int32, count=n + 1 if n else 0)
        self.raw = bytes(b["raw"]) if n else b""
        self.payload_at = np.frombuffer(b["payload_at"], np.int32, count=n + 1 if n else 0)
        self.payload = memoryview(b["payload"])
        self.note = view("note", "u1")  # columns.h MS_NOTE_* bits (zeros unless Columns(notes=True))
        self.signed = (self.iflags & 1).astype(np.bool_)

    def payload_of(self, i: int) -> bytes:
        """The payload of frame `i` of the chunk, as on the wire."""
        return bytes(self.payload[self.payload_at[i]:self.payload_at[i + 1]])

    def raw_of(self, i: int) -> bytes:
        """The wire bytes of frame `i` of the chunk."""
        return self.raw[self.raw_at[i]:self.raw_at[i + 1]]
