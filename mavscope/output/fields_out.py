"""`read -T fields -e FIELD ... [-E option=value ...]`: tshark's fields output over the field registry.

As `tshark -T fields` prints it: one line per capture record (a packet, a tlog entry; a raw stream's frames
are records of their own) that completed at least one shown MAVLink frame, one column per `-e` field in the
order given, a field the record's frames lack empty. A MAVLink field of several frames of one record (a
datagram holding two frames) or one holding several values (`ip.addr`, an array) has several occurrences,
joined as `-E occurrence` and `-E aggregator` say; the record's own fields (`frame.number`, `frame.time*`,
`frame.src`, `ip.*`, `udp.*`, `tcp.*`) occur once a line, as tshark's packet fields do (`frame.index` and
`frame.len` are each MAVLink frame's). A record without a MAVLink frame prints no line, where tshark prints
an empty one (filter with `-Y mavlink_proto` there). Any name the field registry resolves serves: header
fields and verdicts (`mavlink.seq`, `signature.status`), the Lua dissector's spellings
(`mavlink_proto.sequence`, `mavlink_proto.GLOBAL_POSITION_INT_lat`), payload fields (`ATTITUDE.roll`, a bare
`roll` for every message that has it), container fields (`ftp.opcode`), note fields.

`-E` options, as tshark defines them: `header=y|n` (the field names as given, first, never quoted), `separator=/t|/s|C`
(tab, space or a character; tab by default), `quote=d|s|n` (each value in double or single quotes, or none;
a quote inside a value is doubled, as CSV does), `occurrence=f|l|a` (first, last or all of a field's
occurrences), `aggregator=/s|C` (between occurrences; `,` by default).

Values: integers in decimal, float32 payload fields as their shortest text (as every mavscope output),
doubles as Python's repr, bytes as hex, addresses as text, a field that only says it is there (`signature`,
`mavlink.signed`) as `1`. Text from the capture is escaped (`visible`: control characters and escapes as
`\\xNN`), so no capture can write to a terminal or break a line or a column; a separator or aggregator
inside a value is left alone (quote the values to read them back as CSV).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import IO

from mavscope.errors import UsageError
from mavscope.fields.registry import BYTES, MISSING, NONE, Field, FieldRegistry, PayloadField
from mavscope.mavlink.dialect import MessageDef
from mavscope.mavlink.floats import f32_text
from mavscope.mavlink.frame import Frame, decode_payload
from mavscope.output.timefmt import TIME_FIELDS, Clock
from mavscope.visible import visible

OCCURRENCES = ("f", "l", "a")
# fields of the record, not of a MAVLink frame in it: one occurrence a line, as tshark has one a packet
PER_FRAME = frozenset({"frame.index", "frame.len"})
RECORD_PREFIXES = ("frame.", "ip.", "udp.", "tcp.")
QUOTES = {"d": '"', "s": "'", "n": ""}


@dataclass(frozen=True, slots=True)
class FieldsFormat:
    """The `-E` options (tshark's defaults)."""

    header: bool = False
    separator: str = "\t"
    quote: str = ""
    occurrence: str = "a"
    aggregator: str = ","


def _char(value: str, option: str) -> str:
    if value == "/t":
        return "\t"
    if value == "/s":
        return " "
    if len(value) != 1 or value in "\r\n" or not value.isprintable() and value != "\t":
        raise UsageError(f"-E {option}={value}: a separator is /t, /s or one printable character")
    return value


def parse_format(options: Sequence[str]) -> FieldsFormat:
    """The format `-E` options give (UsageError for one tshark does not define, or a bad value)."""
    values: dict[str, object] = {}
    for opt in options:
        key, eq, value = opt.partition("=")
        if not eq:
            raise UsageError(f"-E {opt}: expected option=value (header, separator, quote, occurrence, aggregator)")
        if key == "header":
            if value not in ("y", "n"):
                raise UsageError(f"-E header={value}: y or n")
            values["header"] = value == "y"
        elif key == "separator":
            values["separator"] = _char(value, key)
        elif key == "quote":
            if value not in QUOTES:
                raise UsageError(f"-E quote={value}: d, s or n")
            values["quote"] = QUOTES[value]
        elif key == "occurrence":
            if value not in OCCURRENCES:
                raise UsageError(f"-E occurrence={value}: f, l or a")
            values["occurrence"] = value
        elif key == "aggregator":
            values["aggregator"] = _char(value, key)
        else:
            raise UsageError(f"-E {opt}: unknown option {key!r} (header, separator, quote, occurrence, aggregator)")
    return FieldsFormat(**values)  # type: ignore[arg-type]


def _text(value: object, float32: bool) -> str:
    if value is True:
        return "1"
    if value is False:
        return "0"
    if isinstance(value, float):
        return f32_text(value) if float32 else repr(value)
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value).hex()
    return visible(str(value))


Values = Callable[[Frame, dict[str, object] | None], list[str]]


def _accessor(registry: FieldRegistry, name: str) -> tuple[Values, bool, bool]:
    """How to get `name`'s occurrences in a frame (as text), whether it needs the decoded payload, and
    whether it is a field of the record (its first frame's value serves the line)."""
    got = registry.lookup(name)
    if got is None:
        close = difflib.get_close_matches(name, registry.all_names(), n=1, cutoff=0.75)
        hint = f'; did you mean "{close[0]}"?' if close else ""
        raise UsageError(f"-e {visible(name)}: no such field{hint}")
    if isinstance(got, MessageDef):
        raise UsageError(f"-e {name}: a message, not a field (its fields: {name}.FIELD)")
    if isinstance(got, PayloadField):
        defs, value_of = got.defs, got.value  # (a display-unit companion's value is in its unit)

        def payload(frame: Frame, fields: dict[str, object] | None) -> list[str]:
            value = value_of(frame, fields)
            if value is MISSING:
                return []
            fd = defs[frame.msgid]
            f32 = fd.type == "float"
            return [_text(v, f32) for v in value] if isinstance(value, list) else [_text(value, f32)]

        return payload, True, False
    field: Field = got
    get = field.get

    def header(frame: Frame, _fields: dict[str, object] | None) -> list[str]:
        value = get(frame)
        if value is MISSING:
            return []
        if field.type == NONE:
            return ["1"]
        if field.multi:
            return [_text(v, False) for v in value]  # type: ignore[attr-defined]
        if field.type == BYTES and isinstance(value, (bytes, bytearray)):
            return [value.hex()]
        return [_text(value, False)]

    return header, False, field.name.startswith(RECORD_PREFIXES) and field.name not in PER_FRAME


def _time_accessor(clock: Clock, name: str) -> tuple[Values, bool, bool]:
    """`frame.time*` as tshark prints them (output.timefmt.Clock: the run's first time, the frames before)."""
    return (lambda frame, _fields: [clock.field(name, frame)] if frame.time is not None else []), False, True


class FieldsWriter:
    """Writes the fields lines of the frames given, a line per record (see the module docstring)."""

    def __init__(self, out: IO[str], registry: FieldRegistry, names: Sequence[str], fmt: FieldsFormat,
                 clock: Clock | None = None) -> None:
        if not names:
            raise UsageError("-T fields: name at least one field with -e")
        self.out, self.names, self.fmt = out, list(names), fmt
        self.clock = clock = clock if clock is not None else Clock("r", None)
        got = [_time_accessor(clock, n) if n in TIME_FIELDS else _accessor(registry, n) for n in names]
        self.accessors = [a for a, _, _ in got]
        self.decode = any(d for _, d, _ in got)
        self.per_record = [r for _, _, r in got]
        self.record: int | None = None
        self.values: list[list[str]] = [[] for _ in names]

    def begin(self) -> None:
        if self.fmt.header:
            self.out.write(self.fmt.separator.join(self.names) + "\n")  # (unquoted, as tshark writes them)

    def frame(self, frame: Frame) -> None:
        first = frame.record != self.record
        if first:
            self._flush()
            self.record = frame.record
        fields = decode_payload(frame) if self.decode else None
        for got, accessor, per_record in zip(self.values, self.accessors, self.per_record):
            if first or not per_record:
                got.extend(accessor(frame, fields))
        if first:
            self.clock.show(frame)

    def end(self) -> None:
        self._flush()

    def flush(self) -> None:
        """The record gathered so far as its line, and the stream flushed (`live`, when the link is idle: a
        record's frames all come out of the pipeline before the next record is read)."""
        self._flush()
        self.out.flush()

    def _quoted(self, text: str) -> str:
        q = self.fmt.quote
        return f"{q}{text.replace(q, q + q)}{q}" if q else text

    def _flush(self) -> None:
        if self.record is None:
            return
        fmt = self.fmt
        cells = []
        for got in self.values:
            if fmt.occurrence == "f":
                got = got[:1]
            elif fmt.occurrence == "l":
                got = got[-1:]
            cells.append(self._quoted(fmt.aggregator.join(got)) if got else "")
        self.out.write(fmt.separator.join(cells) + "\n")
        self.values = [[] for _ in self.names]
        self.record = None
