"""What the index hands out: list rows, decoded details, build progress, and the details cache."""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple

from mavscope.endpoint import Endpoint
from mavscope.fields.tree import Item
from mavscope.mavlink.frame import (
    CrcStatus,
    EncryptionStatus,
    Frame,
    Security,
    SignatureStatus,
    frame_number,
    signature_status,
)


class Row(NamedTuple):
    """What the packet list shows of one frame, straight from the index (no decoding)."""

    row: int  # the frame's row number (0-based, kept for good: a bounded index drops rows, never renumbers)
    record: int
    index: int  # type: ignore[assignment]  # shadows tuple.index, as Frame.index does
    time: float | None
    transport: str
    src: Endpoint | None
    dst: Endpoint | None
    sysid: int
    compid: int
    seq: int
    msgid: int
    msgname: str | None
    incompat_flags: int
    crc_status: CrcStatus
    security: Security | None

    @property
    def number(self) -> str:
        return frame_number(self.record, self.index)

    @property
    def signature_status(self) -> SignatureStatus | None:
        return signature_status(self.incompat_flags, self.security)

    @property
    def encryption_status(self) -> EncryptionStatus | None:
        sec = self.security
        if sec is not None and sec.encryption is not None:
            return sec.encryption.status
        return None


@dataclass(frozen=True, slots=True)
class Detail:
    """A frame decoded for display: its fields, detail tree and summary."""

    frame: Frame
    fields: dict[str, object] | None
    items: tuple[Item, ...]
    summary: str


@dataclass(frozen=True, slots=True)
class Progress:
    """How far a build has got: frames indexed, bytes of the capture read (of `total`), finished or not."""

    frames: int
    position: int
    total: int
    done: bool
    cancelled: bool = False

    @property
    def fraction(self) -> float:
        if self.done:
            return 1.0
        return min(1.0, self.position / self.total) if self.total else 0.0


class LRU:
    """A small thread-safe LRU map (the UI and a filter worker may both ask for details)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.data: OrderedDict[int, object] = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key: int) -> object | None:
        with self.lock:
            v = self.data.get(key)
            if v is not None:
                self.data.move_to_end(key)
            return v

    def put(self, key: int, value: object) -> None:
        with self.lock:
            self.data[key] = value
            self.data.move_to_end(key)
            while len(self.data) > self.size:
                self.data.popitem(last=False)

    def clear(self) -> None:
        with self.lock:
            self.data.clear()
