"""Writing captures: classic pcap (one link type) and pcapng (several)."""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Sequence
from types import TracebackType
from typing import BinaryIO

from mavscope.capture.base import LINKTYPE_ETHERNET
from mavscope.capture.pcap import MAGIC_NS, MAGIC_US
from mavscope.capture.pcapng import BT_EPB, BT_IDB, BT_SHB, BYTE_ORDER_MAGIC, OPT_IF_TSRESOL
from mavscope.errors import CaptureError, UsageError

DEFAULT_SNAPLEN = 262144

_PCAP_GLOBAL = struct.Struct("<IHHiIII")
_PCAP_RECORD = struct.Struct("<IIII")
_EPB_HEAD = struct.Struct("<IIIIIII")
OPT_COMMENT = 1  # pcapng opt_comment: a UTF-8 comment, any block
_TLOG_TIME = struct.Struct(">Q")


def _split_time(time: float | None, units: int, max_ticks: int) -> tuple[int, int, bool]:
    """(whole seconds, fraction in 1/units, clamped) of a timestamp for a format that holds 0 .. `max_ticks`
    ticks of 1/units s.

    None (no time) is written as 0 and is not a clamp. A time the format cannot hold is clamped and said
    so: NaN and negative times become 0, +inf and times past the format's end its last tick.
    """
    if time is None:
        return 0, 0, False
    if time != time or time < 0:  # NaN, -inf, negative
        return 0, 0, True
    if time == math.inf or time * units > max_ticks + units:
        sec, frac = divmod(max_ticks, units)
        return sec, frac, True
    sec = math.floor(time)
    frac = round((time - sec) * units)
    if frac >= units:
        sec, frac = sec + 1, frac - units
    if sec * units + frac > max_ticks:
        sec, frac = divmod(max_ticks, units)
        return sec, frac, True
    return sec, frac, False


def _describe(t: float) -> str:
    return f"{t!r} s" if t != t or abs(t) == math.inf else f"{t:.6g} s"


class _Writer:
    """Shared file handling: a path (owned, closed by close()) or a binary file object (left open)."""

    def __init__(self, path_or_fileobj: str | os.PathLike[str] | BinaryIO) -> None:
        if isinstance(path_or_fileobj, (str, os.PathLike)):
            try:
                self._f: BinaryIO = open(path_or_fileobj, "wb")  # noqa: SIM115 - closed in close()
            except OSError as e:
                raise CaptureError(f"cannot write: {e.strerror or e}", path=os.fspath(path_or_fileobj)) from None
            self._owned = True
        else:
            self._f = path_or_fileobj
            self._owned = False
        self.closed = False
        self.clamped = 0  # records whose time the format cannot hold, written clamped (see clamp_message)
        self._first_clamped: float | None = None
        self._format = "pcap"
        self._latest = "2106-02-07T06:28:15Z"  # the last time the format holds (subclasses set it)

    def _clamp(self, time: float) -> None:
        self.clamped += 1
        if self._first_clamped is None:
            self._first_clamped = time

    def clamp_message(self) -> str | None:
        """One line for the user if record times had to be clamped (None if not); names no path."""
        if not self.clamped or self._first_clamped is None:
            return None
        what = "1 record time was" if self.clamped == 1 else f"{self.clamped} record times were"
        return (f"{what} written clamped: {self._format} cannot hold a time that is negative, not a number or "
                f"after {self._latest} (the first was {_describe(self._first_clamped)})")

    def flush(self) -> None:
        """Push everything written so far to the file (a live capture calls this periodically)."""
        self._f.flush()

    def close(self) -> None:
        """Flush, and close the file if this writer opened it (idempotent)."""
        if self.closed:
            return
        self.closed = True
        self._f.flush()
        if self._owned:
            self._f.close()

    def __enter__(self) -> _Writer:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class PcapWriter(_Writer):
    """Writes a little-endian classic pcap file of one link type, in microseconds or nanoseconds."""

    def __init__(
        self,
        path_or_fileobj: str | os.PathLike[str] | BinaryIO,
        linktype: int,
        snaplen: int = DEFAULT_SNAPLEN,
        nanosecond: bool = False,
    ) -> None:
        if not 0 <= linktype <= 0xFFFF:
            raise UsageError(f"pcap link type must be 0..65535, not {linktype}")
        super().__init__(path_or_fileobj)
        self.linktype = linktype
        self.snaplen = snaplen
        self.units = 1_000_000_000 if nanosecond else 1_000_000
        self._max_ticks = (1 << 32) * self.units - 1  # 32-bit seconds, then the fraction
        magic = MAGIC_NS if nanosecond else MAGIC_US
        self._f.write(_PCAP_GLOBAL.pack(magic, 2, 4, 0, 0, snaplen, linktype))

    def write(self, time: float | None, data: bytes, orig_len: int | None = None) -> None:
        """Append one record; data beyond the snap length is cut off (orig_len keeps the real length)."""
        if self.closed:
            raise UsageError("write to a closed PcapWriter")
        orig = max(orig_len if orig_len is not None else len(data), len(data))
        if len(data) > self.snaplen:
            data = data[: self.snaplen]
        sec, frac, clamped = _split_time(time, self.units, self._max_ticks)
        if clamped and time is not None:
            self._clamp(time)
        self._f.write(_PCAP_RECORD.pack(sec, frac, len(data), min(orig, 0xFFFFFFFF)))
        self._f.write(data)

    def write_raw(self, records: bytes) -> None:
        """Append whole records already in this file's format (little-endian 16-byte headers in its time
        resolution, data within its snap length): live capture's batches, made in C."""
        if self.closed:
            raise UsageError("write to a closed PcapWriter")
        self._f.write(records)

    def __enter__(self) -> PcapWriter:
        return self


def _options(comments: Sequence[str]) -> bytes:
    """A block's opt_comment options (code 1) and opt_endofopt, or nothing without a comment."""
    if not comments:
        return b""
    out = []
    for text in comments:
        raw = text.encode("utf-8")[:0xFFFF].decode("utf-8", "ignore").encode("utf-8")  # (whole characters)
        out.append(struct.pack("<HH", OPT_COMMENT, len(raw)) + raw + b"\0" * (-len(raw) & 3))
    return b"".join(out) + struct.pack("<HH", 0, 0)


class PcapngWriter(_Writer):
    """Writes a little-endian pcapng file: one section, one interface per link type, Enhanced Packet Blocks."""

    def __init__(
        self,
        path_or_fileobj: str | os.PathLike[str] | BinaryIO,
        linktype: int | None = None,
        snaplen: int = DEFAULT_SNAPLEN,
        nanosecond: bool = False,
    ) -> None:
        super().__init__(path_or_fileobj)
        self.linktype = linktype  # the default for write()
        self.snaplen = snaplen
        self.nanosecond = nanosecond
        self.units = 1_000_000_000 if nanosecond else 1_000_000
        self._interfaces: dict[int, int] = {}  # link type -> interface id
        self._format = "pcapng"
        self._latest = "2554-07-21T23:34:33Z" if nanosecond else "the year 586524"  # 2**64 - 1 ticks
        body = struct.pack("<IHHq", BYTE_ORDER_MAGIC, 1, 0, -1)
        self._block(BT_SHB, body)

    def _block(self, btype: int, body: bytes) -> None:
        blen = 12 + len(body)
        self._f.write(struct.pack("<II", btype, blen) + body + struct.pack("<I", blen))

    def _interface(self, linktype: int) -> int:
        iface = self._interfaces.get(linktype)
        if iface is None:
            if not 0 <= linktype <= 0xFFFF:
                raise UsageError(f"pcapng link type must be 0..65535, not {linktype}")
            body = struct.pack("<HHI", linktype, 0, self.snaplen)
            if self.nanosecond:
                body += struct.pack("<HHB3x", OPT_IF_TSRESOL, 1, 9) + struct.pack("<HH", 0, 0)
            self._block(BT_IDB, body)
            iface = self._interfaces[linktype] = len(self._interfaces)
        return iface

    def write(
        self, time: float | None, data: bytes, orig_len: int | None = None, linktype: int | None = None,
        comments: Sequence[str] = (),
    ) -> None:
        """Append one packet of `linktype` (default: the writer's), adding its interface on first use;
        `comments`: its opt_comment options (UTF-8, each at most 65,535 bytes: longer ones are cut there)."""
        if self.closed:
            raise UsageError("write to a closed PcapngWriter")
        lt = linktype if linktype is not None else self.linktype
        if lt is None:
            raise UsageError("PcapngWriter.write needs a link type (none given and no default)")
        iface = self._interface(lt)
        orig = max(orig_len if orig_len is not None else len(data), len(data))
        if len(data) > self.snaplen:
            data = data[: self.snaplen]
        sec, frac, clamped = _split_time(time, self.units, (1 << 64) - 1)
        if clamped and time is not None:
            self._clamp(time)
        ts = sec * self.units + frac
        pad = -len(data) & 3
        options = _options(comments)
        blen = 32 + len(data) + pad + len(options)
        self._f.write(_EPB_HEAD.pack(BT_EPB, blen, iface, ts >> 32, ts & 0xFFFFFFFF, len(data),
                                    min(orig, 0xFFFFFFFF)))
        self._f.write(data + b"\0" * pad + options + struct.pack("<I", blen))

    def __enter__(self) -> PcapngWriter:
        return self


class TlogWriter(_Writer):
    """Writes a telemetry log: each entry an 8-byte big-endian time in microseconds, then MAVLink bytes."""

    def __init__(self, path_or_fileobj: str | os.PathLike[str] | BinaryIO) -> None:
        super().__init__(path_or_fileobj)
        self._format = "a tlog"
        self._latest = "the year 586524"  # 2**64 - 1 microseconds

    def write(self, time: float | None, data: bytes) -> None:
        """Append one entry (no time is written as 0)."""
        if self.closed:
            raise UsageError("write to a closed TlogWriter")
        sec, frac, clamped = _split_time(time, 1_000_000, (1 << 64) - 1)
        if clamped and time is not None:
            self._clamp(time)
        self._f.write(_TLOG_TIME.pack(sec * 1_000_000 + frac) + data)

    def __enter__(self) -> TlogWriter:
        return self


__all__ = ["DEFAULT_SNAPLEN", "LINKTYPE_ETHERNET", "PcapWriter", "PcapngWriter", "TlogWriter"]
