"""The base class every capture reader derives from: an open, memory-mapped file yielding Records."""

from __future__ import annotations

import mmap
import os
import stat
import struct
from collections.abc import Iterator
from types import TracebackType

from mavscope.capture.base import Record
from mavscope.errors import CaptureError
from mavscope.notes import Note, note

_tuple_new = tuple.__new__

# What a reader catches around its loop as a last resort (struct.error derives from Exception only)
READER_BUGS: tuple[type[BaseException], ...] = (ValueError, IndexError, OSError, struct.error, OverflowError)


def make_record(
    number: int,
    time: float | None,
    linktype: int,
    data: bytes,
    offset: int,
    orig_len: int,
    notes: tuple[Note, ...] = (),
) -> Record:
    """Build a Record without the NamedTuple constructor's Python-level overhead."""
    return _tuple_new(Record, (number, time, linktype, data, offset, orig_len, notes))


def open_mapped(path: str | os.PathLike[str]) -> tuple[str, object, mmap.mmap | bytes, int]:
    """Open `path` for reading: (path as str, file object, mapping or b"" when empty, size).

    Raises CaptureError for a missing, unreadable or non-regular file.
    """
    spath = os.fspath(path)
    try:
        f = open(spath, "rb")  # noqa: SIM115 - owned by the reader, closed in close()
    except FileNotFoundError:
        raise CaptureError("no such file", path=spath) from None
    except IsADirectoryError:
        raise CaptureError("is a directory, not a capture file", path=spath) from None
    except PermissionError:
        raise CaptureError("permission denied", path=spath) from None
    except OSError as e:
        raise CaptureError(f"cannot open: {e.strerror or e}", path=spath) from None
    try:
        st = os.fstat(f.fileno())
        if not _is_regular(st.st_mode):
            raise CaptureError("not a regular file", path=spath)
        size = st.st_size
        data: mmap.mmap | bytes = b""
        if size:
            data = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    except CaptureError:
        f.close()
        raise
    except (OSError, ValueError) as e:
        f.close()
        raise CaptureError(f"cannot read: {e}", path=spath) from None
    return spath, f, data, size


def close_mapped(file: object | None, buf: mmap.mmap | bytes) -> None:
    """Close what `open_mapped` opened (the mapping first; idempotent on a closed file)."""
    if isinstance(buf, mmap.mmap):
        try:
            buf.close()
        except BufferError:  # a memoryview still exported: let the GC release it
            pass
    if file is not None:
        file.close()  # type: ignore[attr-defined]


def _is_regular(mode: int) -> bool:
    return stat.S_ISREG(mode)


class CaptureReader:
    """An open capture file: a context manager and an iterator of Records.

    `kind` names the format, `size` is the file size and `position` the file offset reached so far.
    Iteration never raises on damaged content: problems become notes on the records.
    """

    kind: str = ""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path, self._file, self._buf, self.size = open_mapped(path)
        self.position = 0
        self._linktype = -2  # the link type of a record the reader makes up (set by subclasses)
        self._iter: Iterator[Record] = self._records()

    def _records(self) -> Iterator[Record]:
        """Yield the file's records, keeping `position` current (subclasses implement).

        Implementations catch READER_BUGS around their loop and end with `failure(...)`, so that not even
        a reader bug escapes iteration.
        """
        raise NotImplementedError

    def failure(self, number: int, offset: int, exc: BaseException, notes: tuple[Note, ...] = ()) -> Record:
        """The last Record of a reader that hit an unexpected error: empty, with a note saying so."""
        self.position = self.size
        msg = f"unreadable from offset {offset} on ({type(exc).__name__}: {exc}); rest skipped"
        return make_record(number, None, self._linktype, b"", offset, 0,
                           notes + (note("capture-garbage", msg, offset),))

    def __iter__(self) -> Iterator[Record]:
        return self._iter

    def __next__(self) -> Record:
        return next(self._iter)

    def close(self) -> None:
        """Release the mapping and the file (idempotent)."""
        buf, self._buf = self._buf, b""
        close_mapped(self._file, buf)

    def __enter__(self) -> CaptureReader:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.path!r} {self.size} bytes>"
