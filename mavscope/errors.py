"""The error hierarchy. Everything mavscope raises on purpose derives from MavscopeError.

Damaged input inside a readable capture is not an error: it becomes a Note on a frame. These
exceptions are for what stops processing (an unreadable file, bad usage, a broken dialect).
"""

from __future__ import annotations


class MavscopeError(Exception):
    """Base class of every error mavscope raises on purpose."""

    def lines(self) -> list[str]:
        """The error as the lines stderr shows (one, but for errors that point into text they quote)."""
        return [str(self)]


class UsageError(MavscopeError):
    """The command line or an API call was given something it cannot use."""


class DialectError(MavscopeError):
    """A MAVLink dialect XML file could not be loaded."""


class DatasetError(MavscopeError):
    """An export dataset directory cannot be used: not a mavscope dataset, or one of another schema version."""


class CaptureError(MavscopeError):
    """A capture file cannot be read (at all, or from `offset` on)."""

    def __init__(self, message: str, offset: int | None = None, path: str | None = None) -> None:
        self.offset = offset
        self.path = path
        where = []
        if path is not None:
            where.append(path)
        if offset is not None:
            where.append(f"offset {offset}")
        super().__init__(f"{': '.join(where)}: {message}" if where else message)
        self.reason = message
