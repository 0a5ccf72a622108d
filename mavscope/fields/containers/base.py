"""What the container dissectors share: field declarations (`Spec`), tree nodes (`Node`) and byte helpers.

A container is a payload field whose bytes carry another protocol or a count of valid bytes
(FILE_TRANSFER_PROTOCOL.payload, LOG_DATA.data...). Its dissector reads the frame's plaintext
payload (zero-filled to the message's length, as the receiver restores a v2 payload whose trailing
zeros the sender trimmed) and never raises: a byte pattern it cannot make sense of becomes fields and
a `*.malformed` text.

This module sits below `fields.registry`, which turns every `Spec` into a registered `Field`, so the
names are declared once, here, and the registry, the tree and the filters share them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, TypeVar

from mavscope.mavlink.dialect import FieldDef, MessageDef
from mavscope.mavlink.frame import Frame, plaintext_payload

# The registry's value types (mavscope.fields.registry: INT, STR, BYTES, NONE); it checks them.
INT, STR, BYTES, NONE = "int", "str", "bytes", "none"

Get = Callable[[Frame], object]  # the value, None where the frame has no such field
Where = Callable[[Frame], "tuple[int, int] | None"]  # (offset in the frame, bytes on the wire)


class Spec(NamedTuple):
    """One container field, as the registry will register it."""

    name: str  # filter name: "ftp.opcode"
    label: str  # tree label: "Opcode"
    type: str  # INT, STR, BYTES or NONE
    get: Get
    span: Where | None = None
    values: tuple[tuple[int, str], ...] = ()  # names of values (first per value: the one shown)
    choices: tuple[str, ...] = ()  # the values a STR field can take
    multi: bool = False  # a tuple of values (one per directory entry)
    description: str = ""


class Node(NamedTuple):
    """A tree node (`fields.tree` turns it into an `Item`)."""

    label: str
    name: str
    offset: int
    length: int
    value: object = None
    children: tuple[Node, ...] = ()
    generated: bool = False


class Region(NamedTuple):
    """The bytes of one payload field: all of them (zero-filled) and where they lie in the frame."""

    base: int  # offset of the field's first byte in the frame
    wire: int  # how many of its bytes the frame carries (v2 senders trim trailing zeros)
    data: bytes  # the field's bytes, zero-filled to its size

    def span(self, start: int, size: int) -> tuple[int, int]:
        """(offset in the frame, bytes on the wire) of `size` bytes at `start` within the field."""
        start = max(0, min(start, len(self.data)))
        return self.base + start, max(0, min(size, self.wire - start))


class Message(NamedTuple):
    """A frame's decoded payload with its definition (what a container dissector starts from)."""

    md: MessageDef
    values: dict[str, object]
    payload: bytes  # the plaintext payload, zero-filled to the message's length

    def region(self, frame: Frame, fd: FieldDef) -> Region:
        data = self.payload[fd.offset : fd.offset + fd.size]
        data += bytes(fd.size - len(data))
        base = frame.header_len + fd.offset
        wire = max(0, min(fd.size, frame.length - fd.offset, len(frame.raw) - base))
        return Region(base, wire, data)

    def uint(self, name: str) -> int:
        """An integer field's value (0 where it is not one: a dialect that defines it otherwise)."""
        v = self.values.get(name)
        return v if isinstance(v, int) else 0


def message(frame: Frame, name: str) -> Message | None:
    """The decoded payload of `frame` if it is message `name` and can be decoded, else None."""
    md = frame.msgdef
    if md is None or md.name != name:
        return None
    payload = plaintext_payload(frame)
    if payload is None:
        return None
    if len(payload) < md.length:
        payload += bytes(md.length - len(payload))
    return Message(md, md.decode(payload), payload)


def byte_field(md: MessageDef, name: str) -> FieldDef | None:
    """`name` in `md` if it is an array of bytes (a container), else None (another dialect's layout)."""
    fd = md.field(name)
    if fd is None or fd.type not in ("uint8_t", "int8_t", "char") or fd.array_length < 1:
        return None
    return fd


T = TypeVar("T")


def memo(fn: Callable[[Frame], T]) -> Callable[[Frame], T]:
    """Remember the last frame's result: the tree and a filter ask a frame for several fields in a row.
    (One slot, replaced atomically: safe for the TUI's worker threads.)"""
    last: list[tuple[Frame | None, T | None]] = [(None, None)]

    def cached(frame: Frame) -> T:
        f, result = last[0]
        if f is frame:
            return result  # type: ignore[return-value]  # set together with `f`
        value = fn(frame)
        last[0] = (frame, value)
        return value
    cached.__doc__ = fn.__doc__
    return cached


def text(raw: bytes) -> tuple[str, bool]:
    """Bytes as text (UTF-8, undecodable bytes escaped) and whether they were valid UTF-8."""
    try:
        return raw.decode("utf-8"), True
    except UnicodeDecodeError:
        return raw.decode("utf-8", "backslashreplace"), False


def plural(n: int) -> str:
    return "1 byte" if n == 1 else f"{n} bytes"


def hex_text(raw: bytes) -> str:
    return raw.hex(" ") if raw else "(none)"


def trimmed(length: int, wanted: int) -> str:
    """The tree's mark for bytes the sender trimmed (v2) and the receiver zero-filled."""
    if length >= wanted:
        return ""
    return " [trimmed: zero-filled]" if length == 0 else " [partly trimmed: zero-filled]"
