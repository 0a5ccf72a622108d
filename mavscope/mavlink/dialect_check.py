"""Dialect files are input: what an XML file must be before pymavlink's parser reads it.

A dialect can come from anyone (a `--dialect` file, one dropped in `dissectors/`, one a capture came
with), and pymavlink's `mavparse` trusts its file: it `eval()`s every enum entry's `value`, builds a
dotted path of every open element at every event (N nested elements cost N squared), grows each
description a piece at a time (`+=`: quadratic in the pieces expat hands it: one per line and per
character reference), and lets expat expand the entities of a DOCTYPE. `check_xml` reads the same bytes
first, with expat as mavparse does (the same pieces: fed 2,048 bytes at a time, pyexpat's buffer), and
refuses, in one line naming the file and what is wrong (DialectError):

- a file over MAX_FILE_BYTES, a DOCTYPE with more than a name (so no entity of any kind, in any
  encoding expat decodes: the check is on the parsed document, not on bytes), elements nested deeper
  than MAX_DEPTH, an element with more than MAX_ATTRIBUTES attributes, more than MAX_ELEMENTS
  elements, more than MAX_TEXT_EVENTS pieces of text, or text whose growth would cost mavparse more
  than MAX_TEXT_COPY bytes of copying (each piece appended copies what its description holds so far:
  counted exactly as mavparse appends);
- names that are not identifiers (`NAME`: ASCII letters, digits and `_`, not starting with a digit, at
  most MAX_NAME characters; message and enum names in upper case, `UPPER_NAME`), as every dialect
  MAVLink ships has them (mavgen's C and Python generators make identifiers of them, and mavscope makes
  file names, SQL views and filter names of them): no `../x`, `/`, NUL, `C:\\x`, space or control
  character reaches a path, a query or a terminal from a dialect;
- a message id that is not a whole number of 0..16777215 (mavschema.xsd's mavlinkMsgId, 24 bits), a
  field type that is not one of MAVLink's (mavschema.xsd's, with an array length of 1..255), more than
  MAX_FIELDS fields in a message (mavparse's own limit, which it checks only after the whole file is
  read), an enum entry value that is not one of mavschema.xsd's forms (decimal,
  0x hex, 0b binary, 2**N: so `eval` only ever sees an integer literal), a command param index that is
  not 1..7.

Over a file and its includes (mavscope.mavlink.dialect's loader): at most MAX_FILES files, includes
MAX_INCLUDE_DEPTH deep, MAX_LOAD_BYTES together, each include a relative path resolving inside the
folder of the file loaded (`include_path`), and mavgen's duplicate rules (`duplicates`).

The limits are above what MAVLink's dialects need, all of them in one file (common.xml, the largest, is
0.7 MB with 6,400 elements, nesting 5 deep, 7 attributes at most, 21,000 pieces of text costing 1.5 MB of
copying; the 19 files pymavlink ships have 9,700 elements and 32,000 pieces together), and low enough
that a file at every limit loads in about a second (1.1 s measured on a loaded 2-core machine, where
common.xml takes 0.25 s; a 5 MB file is refused unread): every dialect of MAVLink's
message_definitions/v1.0 loads (tests/mavlink/test_dialect_input.py). Checking costs one expat pass
with a small handler per event, at most MAX_ELEMENTS + MAX_TEXT_EVENTS events.
"""

from __future__ import annotations

import os
import re
import xml.parsers.expat as expat
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn

from mavscope.errors import DialectError

MAX_FILE_BYTES = 4 << 20  # common.xml: 0.7 MB
MAX_DEPTH = 8  # MAVLink's schema nests 5 deep (mavlink.enums.enum.entry.param)
MAX_ATTRIBUTES = 32  # common.xml: 7 at most
MAX_ELEMENTS = 20_000  # common.xml: 6,400; the 19 dialects pymavlink ships, together: 9,700
MAX_TEXT_EVENTS = 64_000  # pieces of text expat hands mavparse; common.xml: 21,000; all 19: 32,000
MAX_TEXT_COPY = 256 << 20  # bytes mavparse's `+=` copies; common.xml: 1.5 MB
MAX_FIELDS = 64  # mavparse: "Maximum number of field names allowed is 64"
MAX_NAME = 128  # characters; the longest MAVLink name is 63 (an enum entry)
MAX_MESSAGE_ID = (1 << 24) - 1
MAX_ARRAY = 255  # a payload is at most 255 bytes
PIECE = 2048  # pyexpat's ParseFile buffer (mavparse reads the file with it)

NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z", re.ASCII)  # fields, enum entries (GOPRO_RESOLUTION_1080p)
UPPER_NAME = re.compile(r"[A-Z_][A-Z0-9_]*\Z", re.ASCII)  # messages and enums
_MESSAGE_ID = re.compile(r"[0-9]{1,8}\Z", re.ASCII)
# mavschema.xsd's entry values (its patterns are whole-string matches)
_VALUE = re.compile(r"(?:[0-9]{1,20}|0[xX][0-9a-fA-F]{1,16}|0[bB][01]{1,64}|2\*\*[0-9]{1,2})\Z", re.ASCII)
_TYPE = re.compile(r"(?:(?:float|double|char|u?int(?:8|16|32|64)_t)(?:\[([0-9]{1,3})\])?|uint8_t_mavlink_version)\Z",
                   re.ASCII)
_PARAM_INDEX = re.compile(r"[1-7]\Z", re.ASCII)

_MESSAGE = "mavlink.messages.message"
_FIELD = _MESSAGE + ".field"
_ENUM = "mavlink.enums.enum"
_ENTRY = _ENUM + ".entry"
_PARAM = _ENTRY + ".param"
_INCLUDE = "mavlink.include"
# the elements that make one of mavparse's objects (its path holds the parent's: a field is in a message)
_MAKES = {_MESSAGE: "message", _FIELD: "field", _ENUM: "enum", _ENTRY: "entry", _PARAM: "param", _INCLUDE: "include"}
# mavparse's char_data: the paths whose text it appends (`+=`) to an attribute of the last object of a kind
_APPENDS = {_MESSAGE + ".description": "message", _MESSAGE + ".deprecated": "message", _FIELD: "field",
            _ENUM + ".description": "enum", _ENUM + ".deprecated": "enum", _ENTRY + ".description": "entry",
            _ENTRY + ".deprecated": "entry", _PARAM: "param", _INCLUDE: "include"}


def name_problem(name: object, upper: bool = False) -> str | None:
    """Why `name` cannot name a message or an enum (`upper`), a field or an enum entry; None when it can."""
    if not isinstance(name, str):
        return "is not text"
    if len(name) > MAX_NAME:
        return f"is longer than {MAX_NAME} characters"
    if not (UPPER_NAME if upper else NAME).match(name):
        return ("is not an identifier in upper case (A-Z, 0-9, _)" if upper
                else "is not an identifier (letters, digits, _)")
    return None


def names_valid(messages: Iterable[list], enums: Iterable[list]) -> bool:
    """Whether every name of a dialect record's messages and enums (mavscope.mavlink.dialect_cache) is one
    `check_xml` lets through: a cached record is held to the rules of a parsed one."""
    for m in messages:
        if name_problem(m[1], True) or any(name_problem(f[0]) for f in m[7]):
            return False
    for e in enums:
        if name_problem(e[0], True) or any(name_problem(x[0]) for x in e[3]):
            return False
    return True


class _Refused(Exception):
    """Raised inside an expat handler: stops the parse at once."""


def _quoted(text: str, limit: int = 60) -> str:
    """`text` for an error line: in quotes, cut short, as it is (escaped where the line is shown: visible)."""
    return f"'{text if len(text) <= limit else text[:limit] + '...'}'"


class _Checker:
    """The expat handlers: counts, the open elements' dotted paths (as mavparse builds them), and where
    mavparse appends each piece of text."""

    def __init__(self, parser: expat.XMLParserType) -> None:
        self.parser = parser
        self.paths: list[str] = []
        self.elements = 0
        self.events = 0
        self.copied = 0
        # objects mavparse made so far (fields: of the current message); text goes to the last ones
        self.made = {"message": 0, "field": 0, "enum": 0, "entry": 0, "param": 0, "include": 0}
        self.fields = 0
        self.grown: dict[tuple[str, int], int] = {}  # mavparse's text attribute -> its length so far

    def refuse(self, why: str) -> NoReturn:
        raise _Refused(f"line {self.parser.CurrentLineNumber}: {why}")

    def doctype(self, _name: str, system_id: str | None, public_id: str | None, internal: int) -> None:
        """A DOCTYPE is refused unless it is a bare name (`<!DOCTYPE mavlink>`): no internal subset, no
        external one, so no entity can be declared (in whatever encoding the file is)."""
        if internal or system_id is not None or public_id is not None:
            self.refuse("it has a DOCTYPE declaring entities or naming a DTD, which MAVLink dialects do not use")

    def entity(self, *_: object) -> None:
        self.refuse("it declares an XML entity, which MAVLink dialects do not use")

    def start(self, name: str, attrs: dict[str, str]) -> None:
        self.elements += 1
        if self.elements > MAX_ELEMENTS:
            self.refuse(f"more than {MAX_ELEMENTS:,} elements")
        if len(self.paths) >= MAX_DEPTH:
            self.refuse(f"elements nested more than {MAX_DEPTH} deep")
        if len(attrs) > MAX_ATTRIBUTES:
            self.refuse(f"<{_quoted(name)[1:-1]}> has more than {MAX_ATTRIBUTES} attributes")
        path = f"{self.paths[-1]}.{name}" if self.paths else name
        self.paths.append(path)
        kind = _MAKES.get(path)
        if kind is None:
            return
        self.made[kind] += 1
        if kind == "message":
            self.fields = 0
            self._name(attrs, "message", True)
            mid = attrs.get("id")
            if mid is None or not _MESSAGE_ID.match(mid) or int(mid) > MAX_MESSAGE_ID:
                self.refuse(f"message {attrs['name']}: id {_quoted(str(mid))} is not a whole number of "
                            f"0..{MAX_MESSAGE_ID}")
        elif kind == "field":
            self.fields += 1
            if self.fields > MAX_FIELDS:
                self.refuse(f"a message with more than {MAX_FIELDS} fields")
            self._name(attrs, "field")
            type_ = attrs.get("type", "")
            m = _TYPE.match(type_)
            if m is None or (m.group(1) is not None and not 1 <= int(m.group(1)) <= MAX_ARRAY):
                self.refuse(f"field {attrs['name']}: type {_quoted(type_)} is not a MAVLink type (arrays of 1..255)")
        elif kind == "enum":
            self._name(attrs, "enum", True)
        elif kind == "entry":
            self._name(attrs, "enum entry")
            value = attrs.get("value")
            if value is not None and not _VALUE.match(value):
                self.refuse(f"enum entry {attrs['name']}: value {_quoted(value)} is not a whole number "
                            "(decimal, 0x hex, 0b binary or 2**N)")
        elif kind == "param" and not _PARAM_INDEX.match(attrs.get("index", "")):
            self.refuse(f"param index {_quoted(attrs.get('index', ''))} is not 1..7")

    def _name(self, attrs: dict[str, str], what: str, upper: bool = False) -> None:
        name = attrs.get("name")
        if name is None:
            self.refuse(f"a {what} without a name")
        why = name_problem(name, upper)
        if why:
            self.refuse(f"{what} name {_quoted(name)} {why}")

    def end(self, _name: str) -> None:
        self.paths.pop()

    def text(self, data: str) -> None:
        self.events += 1
        if self.events > MAX_TEXT_EVENTS:
            self.refuse(f"more than {MAX_TEXT_EVENTS:,} pieces of text (lines, character references)")
        owner = _APPENDS.get(self.paths[-1]) if self.paths else None
        if owner is None:
            return
        key = (self.paths[-1], self.made[owner])
        size = self.grown.get(key, 0) + len(data)
        self.grown[key] = size
        self.copied += size
        if self.copied > MAX_TEXT_COPY:
            self.refuse("text in too many pieces (lines, character references) for its length")


def too_big(where: str) -> str:
    return (f"{where}: cannot load dialect: over {MAX_FILE_BYTES:,} bytes (common.xml, the largest of MAVLink's "
            "dialects, is about 700,000)")


def check_xml(data: bytes, where: str) -> None:
    """Refuse (DialectError, one line starting with `where`) a dialect file whose bytes are `data` unless it
    is what pymavlink's parser can take in bounded time and memory and every name in it is an identifier
    (the module's docstring)."""
    if len(data) > MAX_FILE_BYTES:
        raise DialectError(too_big(where))
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    check = _Checker(parser)
    parser.StartDoctypeDeclHandler = check.doctype
    parser.EntityDeclHandler = check.entity
    parser.StartElementHandler = check.start
    parser.EndElementHandler = check.end
    parser.CharacterDataHandler = check.text
    try:
        for at in range(0, len(data), PIECE):
            parser.Parse(data[at:at + PIECE], False)
        parser.Parse(b"", True)
    except _Refused as e:
        raise DialectError(f"{where}: cannot load dialect: {e}") from None
    except expat.ExpatError as e:
        raise DialectError(f"{where}: cannot parse dialect: {expat.ErrorString(e.code)} "
                           f"(line {e.lineno}, column {e.offset})") from None


# --- a file and its includes ------------------------------------------------------------------------

MAX_FILES = 64  # files one dialect brings in with its includes (all.xml: 17)
MAX_INCLUDE_DEPTH = 8  # includes of includes (all.xml's go 4 deep; mavgen follows 5: MAXIMUM_INCLUDE_FILE_NESTING)
MAX_LOAD_BYTES = 8 << 20  # a file and its includes together (all.xml's 17 files: 1.3 MB)


def include_path(including: Path, include: str, folder: Path) -> Path:
    """The file an `<include>` of the dialect file `including` names, which must lie in `folder` (the
    folder of the file being loaded) or below it: a relative path, no NUL, backslash or drive, resolved
    (symbolic links followed) inside `folder`. Every dialect MAVLink ships includes a file beside it."""
    where = f"{including}: cannot load dialect: include {_quoted(include)}"
    if not include or "\0" in include or "\\" in include or ":" in include or os.path.isabs(include):
        raise DialectError(f"{where} is not a relative path of a file beside the dialect")
    try:
        target = (including.parent / include).resolve()
    except (OSError, RuntimeError, ValueError) as e:  # a symbolic link loop, a name too long
        raise DialectError(f"{where}: {e}") from None
    if not target.is_relative_to(folder):
        raise DialectError(f"{where} is outside {folder} (an include names a file in the dialect's folder)")
    return target


def duplicates(records: list[tuple[Path, dict[str, Any]]]) -> None:
    """Refuse (DialectError) a dialect whose file and includes define a message id or a message name twice,
    a field twice in one message (or two that differ only in case: SQL and many file systems do not tell
    them apart), an enum entry name or value twice in one enum, or an entry name in two enums: what
    mavgen refuses (mavparse.check_duplicates; C's enum constants share one name space), checked over the
    same set of files mavgen checks, a dialect and its includes."""
    ids: dict[int, tuple[str, Path]] = {}
    names: dict[str, tuple[int, Path]] = {}
    entries: dict[tuple[str, int], tuple[str, Path]] = {}
    entry_names: dict[str, tuple[str, int, Path]] = {}
    for file, record in records:
        where = f"{file}: cannot load dialect:"
        for m in record["messages"]:
            mid, name = m[0], m[1]
            if mid in ids:
                raise DialectError(f"{where} message id {mid} is both {name} and {ids[mid][0]} ({ids[mid][1].name})")
            if name in names:
                raise DialectError(f"{where} message {name} is both id {mid} and id {names[name][0]} "
                                   f"({names[name][1].name})")
            ids[mid], names[name] = (name, file), (mid, file)
            seen: dict[str, str] = {}
            for f in m[7]:
                other = seen.get(f[0].lower())
                if other is not None:
                    raise DialectError(f"{where} message {name} has field {f[0]} twice" if other == f[0] else
                                       f"{where} message {name} has fields {other} and {f[0]}, which differ only in "
                                       "case (SQL and many file systems do not tell them apart)")
                seen[f[0].lower()] = f[0]
        for e in record["enums"]:
            for entry in e[3]:
                key = (e[0], entry[1])
                if key in entries:
                    raise DialectError(f"{where} enum {e[0]} value {entry[1]} is both {entry[0]} and "
                                       f"{entries[key][0]} ({entries[key][1].name})")
                named = entry_names.get(entry[0])
                if named is not None:
                    raise DialectError(f"{where} enum entry {entry[0]} is both {e[0]} {entry[1]} and "
                                       f"{named[0]} {named[1]} ({named[2].name})")
                entries[key], entry_names[entry[0]] = (entry[0], file), (e[0], entry[1], file)
