"""Summary lines (`mavscope read FILE`) on the native engine: what C needs per message, and the driver.

The C writer (src/mavscope_native/summary.c) makes the line output/text.py `summary_line` makes, byte for
byte, for the frames of clean records (the records the JSON Lines walk writes natively, docs/native.md);
every other record is handed back to the Python pipeline, whose lines are `summary_line` itself.

What a message's Info column shows is not written twice: `build_summary_table` compiles, per message of
the loaded Dialect, the plan fields/summary.py `summary_plan` makes for the pure path (SUMMARY_FIELDS or
the first scalar fields, enum names, degE7 as degrees) into the byte string `_native.Summary` takes (its
layout: summary.h), beside the layout table of mavscope.native. The command messages' param1 is named
as semantics.command_param_name names it: per MAV_CMD entry, the names of its param 1's enum or, for a
"Message ID" param, the dialect's message names; for a bitmask, the names of the bits (Enum.flags_of). A
command message's parameters the MAV_CMD entry leaves unlabelled are left out when they hold nothing
(semantics.param_shown, as fields/summary.py and `commands`): per entry, which of params 1..7 it labels.
Containers (FILE_TRANSFER_PROTOCOL shows the inner protocol) and STATUSTEXT (a chunk says which) are
marked Python-only (fields/summary.py PYTHON_INFO), so their records are handed back.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable
from typing import IO

from mavscope.capture.reader import WINDOW
from mavscope.fields.summary import DEGREES, ENUM, PLAIN, PYTHON_IF, PYTHON_INFO, summary_plan
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.semantics import COMMAND_MESSAGES, COMMAND_PARAM_INDEX, MESSAGE_ID_LABELS
from mavscope.native.core import _native
from mavscope.native.table_blob import python_only as layout_python_only
from mavscope.native.tables import table_for
from mavscope.native.walk import Reporter, write_lines
from mavscope.output.text import summary_line
from mavscope.security.stage import SecurityStage
from mavscope.visible import visible

SUMMARY_MAGIC = b"MSSM"
SUMMARY_VERSION = 3
NO_FIELD = 0xFFFF

# the integer wire types and the values they hold; other types (float, double, char, arrays) are shown
# by their value's type whatever the plan says, as fields/summary.py `_short` does
_INT_RANGES: dict[str, tuple[int, int]] = {
    "uint8_t": (0, 0xFF),
    "uint8_t_mavlink_version": (0, 0xFF),
    "int8_t": (-0x80, 0x7F),
    "uint16_t": (0, 0xFFFF),
    "int16_t": (-0x8000, 0x7FFF),
    "uint32_t": (0, 0xFFFF_FFFF),
    "int32_t": (-0x8000_0000, 0x7FFF_FFFF),
    "uint64_t": (0, 0xFFFF_FFFF_FFFF_FFFF),
    "int64_t": (-0x8000_0000_0000_0000, 0x7FFF_FFFF_FFFF_FFFF),
}
_U64 = (1 << 64) - 1


def _text(s: str) -> bytes | None:
    """A name or label as the C table holds it, escaped as fields/summary.py shows it (`visible`): UTF-8, at
    most 255 bytes, no newline; else None."""
    b = visible(s).encode("utf-8")
    return b if len(b) <= 255 and b"\n" not in b else None


def _entries(names: dict[int, str], lo: int, hi: int) -> bytes | None:
    """Value -> name entries in [lo, hi], sorted; None when a name cannot go to C."""
    out: list[bytes] = []
    for value, text in sorted(names.items()):
        name_b = _text(text)
        if name_b is None:
            return None
        if lo <= value <= hi:
            out.append(struct.pack("<QB", value & _U64, len(name_b)) + name_b)
    return struct.pack("<I", len(out)) + b"".join(out)


CMD_PYTHON, CMD_BITS = 1, 2  # summary.h MS_CMD_*


def _command_names(dialect: Dialect, command: int) -> tuple[int, dict[int, str]]:
    """What semantics.command_param_name calls the whole values of param 1 of MAV_CMD `command`: (flags,
    value -> name), CMD_BITS when the names are of bits (Enum.flags_of); {} where it names none."""
    enum = dialect.command_param_enum(command, 1)
    if enum:
        e = dialect.enums.get(enum)
        if e is None:
            return 0, {}
        return (CMD_BITS if e.bitmask else 0), {v: entry.name for v, entry in e.entries.items()}
    if any(i == 1 and label in MESSAGE_ID_LABELS for i, label, _ in dialect.command_params(command)):
        return 0, {msgid: m.name for msgid, m in dialect.messages.items()}
    return 0, {}


def _labelled(dialect: Dialect, command: int) -> int:
    """The params MAV_CMD `command` labels (Dialect.command_params), bit i - 1 for param i."""
    return sum({1 << (i - 1) for i, label, _ in dialect.command_params(command) if 1 <= i <= 7 and label})


def _commands(dialect: Dialect) -> bytes:
    """The command table of a command message (summary.h): per MAV_CMD entry with param 1 names or a label.
    (A command field holds at most 32 bits, _command_fields: an entry beyond int64 is never sent.)"""
    mav_cmd = dialect.enums.get("MAV_CMD")
    parts: list[bytes] = []
    for command in sorted(mav_cmd.entries if mav_cmd is not None else ()):
        if not -(1 << 63) <= command < (1 << 63):
            continue
        flags, names = _command_names(dialect, command)
        labelled = _labelled(dialect, command)
        if not names and not labelled:
            continue
        if flags & CMD_BITS and min(names) < 0:
            flags, names = CMD_PYTHON, {}
        table = _entries(names, -(1 << 63), (1 << 63) - 1)
        if table is None:
            flags, table = CMD_PYTHON, struct.pack("<I", 0)
        parts.append(struct.pack("<qBB", command, flags, labelled) + table)
    return struct.pack("<I", len(parts)) + b"".join(parts)


_NO_COMMAND = struct.pack("<HHI", NO_FIELD, NO_FIELD, 0)
_COMMAND_TYPES = frozenset(t for t in _INT_RANGES if "64" not in t)  # summary.c int_at: exact in int64


def _command_fields(md: MessageDef, commands: Callable[[], bytes]) -> bytes | None:
    """The command part of a message's header: a command message's param1 and command fields and the
    command table (`commands()`); None when they are not a float and an integer of at most 32 bits (Python's)."""
    index = {f.name: i for i, f in enumerate(md.fields)}
    p1, cmd = md.field("param1"), md.field("command")
    if md.name not in COMMAND_MESSAGES:
        return _NO_COMMAND
    if cmd is None or cmd.type not in _COMMAND_TYPES or cmd.array_length:
        return None
    if p1 is not None and (p1.type != "float" or p1.array_length):
        return None
    return struct.pack("<HH", NO_FIELD if p1 is None else index["param1"], index["command"]) + commands()


def _message_entry(md: MessageDef, dialect: Dialect, commands: Callable[[], bytes]) -> bytes:
    """One message of the summary table: header, name, plan items (see summary.h for the layout)."""
    # a layout the layout table leaves to Python (over 255 bytes...) has no fields there to point at
    python_only = md.name in PYTHON_INFO or layout_python_only(md)
    index = {f.name: i for i, f in enumerate(md.fields)}
    items: list[bytes] = []
    for name, how, names in summary_plan(md, dialect):
        i = index[name]
        fd = md.fields[i]
        label = _text(f"{name}=")
        scalar_int = fd.type in _INT_RANGES and not fd.array_length
        # a command's parameter: left out when unlabelled and holding nothing (numbers only: C compares them)
        param = COMMAND_PARAM_INDEX.get(name, 0) if md.name in COMMAND_MESSAGES else 0
        if param and not (scalar_int or (fd.type in ("float", "double") and not fd.array_length)):
            python_only = True
        entries: bytes | None = struct.pack("<I", 0)
        if how == ENUM and scalar_int:  # an empty name shows the number, as _short does
            entries = _entries({v: t for v, t in names.items() if t}, *_INT_RANGES[fd.type])
        if label is None or entries is None:
            python_only = True
            continue
        code = how if scalar_int and how in (ENUM, DEGREES) else PLAIN
        items.append(struct.pack("<HBBB", i, code, param, len(label)) + label + entries)
    title = _text(md.name)
    if title is None or len(items) > 255:
        python_only, title = True, b"?"
    command = _command_fields(md, commands)
    if python_only or command is None:
        python_only, items, command = True, [], _NO_COMMAND
    flags, python_if = int(python_only), b""
    watched = PYTHON_IF.get(md.name, "")
    decides = md.field(watched) if watched and not python_only else None
    if decides is not None:
        if decides.type not in _COMMAND_TYPES or decides.array_length:
            flags, items, command = 1, [], _NO_COMMAND  # (a dialect's other `id`: the line is Python's)
        else:  # a scalar integer of at most 32 bits (summary.c int_at)
            flags, python_if = flags | 2, struct.pack("<H", index[watched])
    return (struct.pack("<IBBH", md.id, flags, len(items), len(title)) + title + python_if + command
            + b"".join(items))


def build_summary_table(dialect: Dialect) -> bytes:
    """What the summary of every message of `dialect` shows, as the blob of `_native.Summary` (in the
    order of mavscope.native.table_blob.build_table: by message id)."""
    made: list[bytes] = []

    def commands() -> bytes:  # the same for every command message: made once
        if not made:
            made.append(_commands(dialect))
        return made[0]

    entries = [_message_entry(md, dialect, commands)
               for md in sorted(dialect.messages.values(), key=lambda m: m.id)]
    return SUMMARY_MAGIC + struct.pack("<II", SUMMARY_VERSION, len(entries)) + b"".join(entries)


# the last Dialect compiled, its Table and its summary table
_summary: list[tuple[Dialect, _native.Table, _native.Summary]] = []


def summary_for(dialect: Dialect) -> _native.Summary:
    """The compiled `_native.Summary` of `dialect` (over `table_for(dialect)`), built once per Dialect."""
    if _native is None:
        raise RuntimeError("mavscope._native is not built")
    table = table_for(dialect)  # (a Summary is over one Table: table_for keeps the last Dialect's only)
    if not _summary or _summary[0][0] is not dialect or _summary[0][1] is not table:
        _summary[:] = [(dialect, table, _native.Summary(table, build_summary_table(dialect)))]
    return _summary[0][2]


def write_summary(path: str | os.PathLike[str], dialect: Dialect, stage: SecurityStage, out: IO[bytes],
                  problems: Reporter, t0: float | None, count: int | None = None, threaded: bool = True,
                  progress: Callable[[int], None] | None = None, kind: str | None = None,
                  window: int = WINDOW) -> dict[str, int]:
    """`read FILE` (summary lines, UTF-8) of a whole capture, times relative to `t0` (the first record's,
    as the pure path's session has it), stopping after `count` frames when given (`-c`): native lines
    and, for handed-back records, `summary_line` of the Python pipeline's frames, in capture order.
    Problems go to `problems`; returns the walk's counters, `frames` and `size` (as write_jsonl)."""

    def render(frame: Frame) -> bytes:
        return (summary_line(frame, dialect, t0) + "\n").encode("utf-8")

    return write_lines(path, dialect, stage, out, problems, render, summary=summary_for(dialect), t0=t0,
                       count=count, threaded=threaded, progress=progress, kind=kind, window=window)
