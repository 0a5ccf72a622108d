"""The base class every capture reader derives from: an open file read in windows, yielding Records.

Files are read with `os.pread` into windows of `WINDOW` bytes, never memory-mapped: a mapped file that
shrinks while it is read (log rotation, a restarted writer truncating it) kills the process with SIGBUS,
which Python cannot catch. A read cannot fault; a short read tells the reader the file shrank, and the
reader ends there with a `record-truncated` note saying so.
"""

from __future__ import annotations

import os
import stat
import struct
from collections.abc import Iterator
from types import TracebackType
from typing import BinaryIO

from mavscope.capture.base import Record
from mavscope.capture.stream import STDIN, STREAM_WINDOW, UNKNOWN_SIZE, StreamBytes
from mavscope.errors import CaptureError
from mavscope.notes import Note, note

_tuple_new = tuple.__new__

# What a reader catches around its loop as a last resort (struct.error derives from Exception only)
READER_BUGS: tuple[type[BaseException], ...] = (ValueError, IndexError, OSError, struct.error, OverflowError)

# Bytes read at a time. 1 MiB: a few thousand records per read(2), small enough to stay in cache; a
# record or block longer than this is read whole (their lengths are bounded by each format's reader).
WINDOW = 1 << 20


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


# A record the native walker hands back to the Python pipeline: (number, time, linktype, data, offset,
# orig_len, notes as (code, message, offset)), as src/mavscope_native/module.c's handback_tuple makes it
HandedBack = tuple[int, float | None, int, bytes, int, int, tuple[tuple[str, str, int], ...]]


def handed_back_record(seg: HandedBack) -> Record:
    """A record the native walker handed back, as the Python readers would have yielded it."""
    number, time, linktype, data, offset, orig_len, notes = seg
    return make_record(number, time, linktype, data, offset, orig_len,
                       tuple(note(code, message, off) for code, message, off in notes))


def open_file(path: str | os.PathLike[str]) -> tuple[str, BinaryIO, int]:
    """Open `path` for reading: (path as str, unbuffered file object, size).

    Raises CaptureError for a missing, unreadable or non-regular file.
    """
    spath = os.fspath(path)
    try:
        f = open(spath, "rb", buffering=0)  # noqa: SIM115 - owned by the caller, closed by it
    except FileNotFoundError:
        raise CaptureError("no such file", path=spath) from None
    except IsADirectoryError:
        raise CaptureError("is a directory, not a capture file", path=spath) from None
    except PermissionError:
        raise CaptureError("permission denied", path=spath) from None
    except OSError as e:
        raise CaptureError(f"cannot open: {e.strerror or e}", path=spath) from None
    except ValueError:  # a NUL byte in the name
        raise CaptureError("not a usable file name", path=repr(spath)) from None
    try:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise CaptureError("not a regular file", path=spath)
    except CaptureError:
        f.close()
        raise
    except OSError as e:
        f.close()
        raise CaptureError(f"cannot read: {e.strerror or e}", path=spath) from None
    return spath, f, st.st_size


def pread(f: BinaryIO, n: int, offset: int) -> bytes:
    """Up to `n` bytes of `f` from `offset`: fewer only at the end of the file. Never moves a file position
    that another thread might use (os.pread where the platform has it)."""
    if n <= 0:
        return b""
    if _PREAD is not None:
        fd = f.fileno()
        data = _PREAD(fd, n, offset)
        if len(data) < n and data:  # a regular file returns short only at its end; make sure
            parts = [data]
            got = len(data)
            while got < n:
                more = _PREAD(fd, n - got, offset + got)
                if not more:
                    break
                parts.append(more)
                got += len(more)
            data = b"".join(parts)
        return data
    f.seek(offset)
    return f.read(n) or b""


_PREAD = getattr(os, "pread", None)


class FileBytes:
    """Random access to the bytes of an open file (owned: `close` closes it), without a memory mapping.

    Requests that move forward are served from a window of `window` bytes read ahead, so a sequential
    walk costs one read(2) per window; a request behind the window is read on its own (the window only
    moves forward, so the bytes read in windows never exceed the file size plus one window). Thread-safe:
    the window is one tuple, replaced whole.
    """

    __slots__ = ("_f", "_win", "window")

    def __init__(self, f: BinaryIO, window: int = WINDOW) -> None:
        self._f = f
        self.window = window
        self._win: tuple[int, bytes] = (0, b"")

    def get(self, offset: int, n: int, exact: bool = False) -> bytes:
        """The `n` bytes at `offset`: fewer where the file ends (b"" past it or for a negative offset), or
        with `exact` an IndexError saying the file shrank."""
        base, buf = self._win
        rel = offset - base
        if 0 <= rel and rel + n <= len(buf) and n > 0:  # the common case: in the window
            return buf[rel:rel + n]
        data = self._get(offset, n)
        if exact and len(data) < n:
            raise IndexError(f"the file shrank: the {n} bytes at offset {offset} are no longer there")
        return data

    def _get(self, offset: int, n: int) -> bytes:
        if offset < 0 or n <= 0:
            return b""
        base, buf = self._win
        rel = offset - base
        if 0 <= rel and rel + n <= len(buf):
            return buf[rel:rel + n]
        if offset >= base + len(buf) and n <= self.window:
            buf = pread(self._f, self.window, offset)
            self._win = (offset, buf)
            return buf[:n]
        return pread(self._f, n, offset)

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._win = (0, b"")
        self._f.close()


class CaptureReader:
    """An open capture file: a context manager and an iterator of Records.

    `kind` names the format, `size` is the file size and `position` the file offset reached so far. If
    the file shrinks while it is read, `size` becomes the offset where its bytes ran out (and
    `opened_size` keeps the size it had when opened). Iteration never raises on damaged content:
    problems become notes on the records.
    """

    kind: str = ""
    window: int = WINDOW  # bytes read at a time (tests make it small to cross many window boundaries)

    def __init__(self, path: str | os.PathLike[str] | StreamBytes) -> None:
        self._stream: StreamBytes | None = None
        self._file: BinaryIO | None
        if isinstance(path, StreamBytes):  # standard input (capture.stream): its size is known at its end
            self.path, self._file, self.size, self._stream = STDIN, None, UNKNOWN_SIZE, path
            self.window = STREAM_WINDOW
        else:
            self.path, self._file, self.size = open_file(path)
        self.opened_size = self.size
        self.position = 0
        self._linktype = -2  # the link type of a record the reader makes up (set by subclasses)
        self._iter: Iterator[Record] = self._records()

    def _records(self) -> Iterator[Record]:
        """Yield the file's records, keeping `position` current (subclasses implement).

        Implementations catch READER_BUGS around their loop and end with `failure(...)`, so that not even
        a reader bug escapes iteration; they add `shrink_notes()` to their last record.
        """
        raise NotImplementedError

    def read_at(self, offset: int, n: int) -> bytes:
        """Up to `n` bytes from `offset`, never past `size`. A short read before `size` means the file
        shrank: `size` drops to where its bytes ended."""
        want = min(n, self.size - offset)
        if want <= 0:
            return b""
        if self._stream is not None:
            data = self._stream.read_at(offset, want)
            if len(data) < want:  # the stream ended: its size (not a file that shrank)
                self.size = self.opened_size = offset + len(data)
            return data
        assert self._file is not None
        data = pread(self._file, want, offset)
        if len(data) < want:
            self.size = offset + len(data)
        return data

    def window_at(self, offset: int, need: int = 0) -> bytes:
        """The bytes from `offset`: at least `need` of them (a whole record) and a window, where the file
        has them."""
        return self.read_at(offset, max(need, self.window))

    def shrink_notes(self) -> tuple[Note, ...]:
        """A note saying the file shrank while it was read, if it did (for the reader's last record)."""
        if self.size >= self.opened_size:
            return ()
        return (note("record-truncated", f"the file shrank while it was read: its bytes ended at offset {self.size} "
                     f"of the {self.opened_size} it had when opened; the rest is lost", self.size),)

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
        """Close the file (idempotent; standard input is left open)."""
        if self._file is not None:
            self._file.close()

    def __enter__(self) -> CaptureReader:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.path!r} {self.size} bytes>"
