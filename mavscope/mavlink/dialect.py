"""MAVLink dialects: message and enum definitions compiled from the XML through pymavlink's parser.

Each message is compiled once into a `struct.Struct` for its full wire layout (base fields sorted by
type size, then extensions), a tuple of field definitions with their payload offsets, and a decoder
that turns a payload into a dict of raw wire values. Layouts are never written by hand: pymavlink's
`mavparse` computes field order and CRC_EXTRA from the XML. What it gives for each file is kept as plain
data (a record), cached between runs: `mavscope.mavlink.dialect_cache`.
"""

from __future__ import annotations

import os
import struct
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path

from mavscope.errors import DialectError
from mavscope.mavlink.dialect_cache import Record, cache_dir, record_of
from mavscope.mavlink.dialect_check import MAX_FILES, MAX_INCLUDE_DEPTH, MAX_LOAD_BYTES, duplicates, include_path
from mavscope.visible import visible

# Wire type -> struct code (little-endian). `uint8_t_mavlink_version` is HEARTBEAT's constant field.
_STRUCT_CODE = {
    "float": "f",
    "double": "d",
    "char": "s",
    "int8_t": "b",
    "uint8_t": "B",
    "uint8_t_mavlink_version": "B",
    "int16_t": "h",
    "uint16_t": "H",
    "int32_t": "i",
    "uint32_t": "I",
    "int64_t": "q",
    "uint64_t": "Q",
}

Decoded = dict[str, object]


@dataclass(frozen=True, slots=True)
class EnumEntry:
    name: str
    value: int
    description: str
    # For MAV_CMD entries: param index (1..7) -> (label, units); empty for other enums.
    params: tuple[tuple[int, str, str], ...] = ()
    # For MAV_CMD entries: param index -> the enum that names its values (the XML's enum="...")
    param_enums: tuple[tuple[int, str], ...] = ()


@dataclass(frozen=True, slots=True)
class EnumDef:
    name: str
    bitmask: bool
    entries: dict[int, EnumEntry]
    by_name: dict[str, EnumEntry]
    description: str = ""

    def name_of(self, value: int) -> str | None:
        """The entry name for `value`, or None."""
        entry = self.entries.get(value)
        return entry.name if entry is not None else None

    def flags_of(self, value: int) -> list[str]:
        """Names of the bits set in `value` (a bitmask enum); unknown bits as hex."""
        names: list[str] = []
        rest = value
        for bit_value, entry in sorted(self.entries.items()):
            if bit_value and value & bit_value == bit_value:
                names.append(entry.name)
                rest &= ~bit_value
        if rest:
            names.append(f"0x{rest:x}")
        return names


@dataclass(frozen=True, slots=True)
class FieldDef:
    """One payload field: where it lies on the wire and how to show it."""

    name: str
    message: str
    type: str  # MAVLink type name: uint8_t, float, char...
    array_length: int  # 0 for scalars
    offset: int  # byte offset in the payload
    size: int  # bytes on the wire
    extension: bool
    units: str
    enum: str
    display: str  # "bitmask" or ""
    description: str
    print_format: str

    @property
    def filter_name(self) -> str:
        return f"{self.message}.{self.name}"

    @property
    def wireshark_name(self) -> str:
        return f"mavlink_proto.{self.message}_{self.name}"


@dataclass(frozen=True, slots=True)
class MessageDef:
    """A compiled message: id, CRC_EXTRA, wire layout and decoder."""

    id: int
    name: str
    crc_extra: int
    fields: tuple[FieldDef, ...]  # wire order
    base_length: int  # payload bytes of the base fields (all a v1 frame carries)
    length: int  # payload bytes including extensions
    description: str
    source: str  # dialect file that defined it
    crc_extra_byte: bytes = field(repr=False, compare=False)
    decode: Callable[[bytes], Decoded] = field(repr=False, compare=False)
    # `decode` of many payloads (at most `length` bytes each) in one call (_make_many_decoder)
    decode_many: Callable[[list[bytes]], list[Decoded]] = field(default=lambda _p: [], repr=False, compare=False)
    xml_order: tuple[str, ...] = ()  # field names in XML order (pymavlink's `fieldnames`; CSV columns)
    # its char arrays that hold strings (wire order): those whose bytes after the NUL are noted (char-after-nul)
    chars: tuple[FieldDef, ...] = field(default=(), repr=False, compare=False)

    def field(self, name: str) -> FieldDef | None:
        for f in self.fields:
            if f.name == name:
                return f
        return None


def _field_code(f: FieldDef) -> str:
    code = _STRUCT_CODE[f.type]
    if f.type == "char":
        return f"{max(f.array_length, 1)}s"
    if f.array_length:
        return f"{f.array_length}{code}"
    return code


def wire_format(fields: Iterable[FieldDef]) -> str:
    """The `struct` format of a payload with `fields` (wire order): a char array is one bytes item, any
    other array one item per element."""
    return "<" + "".join(_field_code(f) for f in fields)


def char_text(raw: bytes) -> str:
    """A char array's value: its bytes up to the first NUL (common.xml: PARAM_VALUE.param_id "terminated by
    NULL if the length is less than 16"; pymavlink's generated messages keep `value.split(b"\\x00", 1)[0]`,
    MAVLink's C++ library `strnlen`, C readers hand the array to C string functions), UTF-8 with undecodable
    bytes shown escaped. The bytes after that NUL are no part of the value (`char_tail`)."""
    end = raw.find(0)
    return (raw if end < 0 else raw[:end]).decode("utf-8", errors="backslashreplace")


def char_tail(raw: bytes) -> int:
    """How many bytes of a char array follow the NUL that ends its value, up to its last byte that is not
    NUL (0: only NULs, or none, follow it): what a sender put where no reader of the string looks."""
    end = raw.find(0)
    return 0 if end < 0 else max(0, len(raw.rstrip(b"\x00")) - end - 1)


# char arrays that carry a value's bytes, not text: PARAM_EXT_*.param_value (the extended parameter protocol:
# MAV_PARAM_EXT_TYPE says what its bytes are, a float's or an integer's little-endian bytes, text only for
# CUSTOM), where a NUL is one of the value's bytes
VALUE_BYTES = frozenset({("PARAM_EXT_VALUE", "param_value"), ("PARAM_EXT_SET", "param_value"),
                         ("PARAM_EXT_ACK", "param_value")})


def is_text(fd: FieldDef) -> bool:
    """Whether char array `fd` holds a string (`char_text`), not a value's bytes (VALUE_BYTES: `bytes_text`)."""
    return (fd.message, fd.name) not in VALUE_BYTES


def bytes_text(raw: bytes) -> str:
    """A char array that carries a value's bytes (VALUE_BYTES): all of them but the trailing NULs (the
    sender's padding), UTF-8 with undecodable bytes shown escaped: a NUL inside is one of the bytes."""
    return raw.rstrip(b"\x00").decode("utf-8", errors="backslashreplace")


def char_value(fd: FieldDef) -> Callable[[bytes], str]:
    """How char array `fd`'s value is made from its bytes: `char_text`, or `bytes_text` for VALUE_BYTES."""
    return char_text if is_text(fd) else bytes_text


def _make_many_decoder(fields: tuple[FieldDef, ...], length: int) -> Callable[[list[bytes]], list[Decoded]]:
    """`_make_decoder`'s decoder of many payloads at once: for scalar fields only, one struct.iter_unpack over
    the payloads padded to `length` (the Struct `decode` unpacks with); else `decode` of each."""
    if not all(f.array_length == 0 and f.type != "char" for f in fields):
        one = _make_decoder(fields, length)
        return lambda payloads: [one(p) for p in payloads]
    iter_unpack, names = struct.Struct(wire_format(fields)).iter_unpack, tuple(f.name for f in fields)
    return lambda payloads: [dict(zip(names, t)) for t in iter_unpack(b"".join(
        p if len(p) == length else p.ljust(length, b"\0") for p in payloads))]


def _make_decoder(fields: tuple[FieldDef, ...], length: int) -> Callable[[bytes], Decoded]:
    """Build the payload decoder: pad to `length`, unpack once, regroup arrays and strings."""
    st = struct.Struct(wire_format(fields))
    assert st.size == length, (st.size, length)
    unpack = st.unpack_from
    names = tuple(f.name for f in fields)
    simple = all(f.array_length == 0 and f.type != "char" for f in fields)

    if simple:

        def decode_simple(payload: bytes) -> Decoded:
            if len(payload) < length:
                payload = payload + bytes(length - len(payload))
            return dict(zip(names, unpack(payload)))

        return decode_simple

    # (name, first index in the flat tuple, count, kind) with kind: 0 scalar, 1 string, 2 array, 3 a char
    # array of a value's bytes
    plan: list[tuple[str, int, int, int]] = []
    i = 0
    for f in fields:
        if f.type == "char":
            plan.append((f.name, i, 1, 1 if is_text(f) else 3))
            i += 1
        elif f.array_length:
            plan.append((f.name, i, f.array_length, 2))
            i += f.array_length
        else:
            plan.append((f.name, i, 1, 0))
            i += 1
    steps = tuple(plan)

    def decode_shaped(payload: bytes) -> Decoded:
        if len(payload) < length:
            payload = payload + bytes(length - len(payload))
        flat = unpack(payload)
        out: Decoded = {}
        for name, start, count, kind in steps:
            if kind == 0:
                out[name] = flat[start]
            elif kind == 1:
                out[name] = char_text(flat[start])
            elif kind == 3:
                out[name] = bytes_text(flat[start])
            else:
                out[name] = list(flat[start : start + count])
        return out

    return decode_shaped


def _compile_message(m: list, source: str) -> MessageDef:
    """A message of a dialect file's record (mavscope.mavlink.dialect_cache.xml_record) compiled."""
    mid, name, crc_extra, base_length, length, description, xml_order, fields = m
    ftuple = tuple(FieldDef(f[0], name, f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8], f[9], f[10]) for f in fields)
    return MessageDef(
        id=mid,
        name=name,
        crc_extra=crc_extra,
        fields=ftuple,
        base_length=base_length,
        length=length,
        description=description,
        source=source,
        crc_extra_byte=bytes((crc_extra,)),
        decode=_make_decoder(ftuple, length),
        decode_many=_make_many_decoder(ftuple, length),
        xml_order=tuple(xml_order),
        chars=tuple(f for f in ftuple if f.type == "char" and is_text(f)),
    )


def _parse_files(root: Path, cache: Path | None = None) -> list[tuple[Path, Record]]:
    """The records of `root` and, breadth first, of every file it includes (from the cache in `cache`, a
    directory, or parsed by pymavlink), each once (an include cycle ends there, as in mavgen). Bounded:
    at most MAX_FILES files, MAX_INCLUDE_DEPTH includes deep, MAX_LOAD_BYTES in all, every include inside
    `root`'s folder (dialect_check.include_path)."""
    top = root.resolve()
    folder = top.parent
    done: dict[Path, Record] = {}
    queue: list[tuple[Path, int, Path | None]] = [(top, 0, None)]
    queued = {top}
    total = 0
    while queue:
        path, depth, by = queue.pop(0)
        if not path.is_file():
            raise DialectError(f"{path}: dialect file not found" + (f" (included by {by})" if by else ""))
        if len(done) == MAX_FILES:
            raise DialectError(f"{root}: cannot load dialect: it includes more than {MAX_FILES} files")
        total += path.stat().st_size
        if total > MAX_LOAD_BYTES:
            raise DialectError(f"{root}: cannot load dialect: it and its includes are over {MAX_LOAD_BYTES:,} bytes")
        record = record_of(path, cache)
        done[path] = record
        for inc in record["include"]:
            target = include_path(path, inc, folder)
            if target in queued:
                continue
            if depth == MAX_INCLUDE_DEPTH:
                raise DialectError(f"{path}: cannot load dialect: includes nested more than {MAX_INCLUDE_DEPTH} deep")
            queued.add(target)
            queue.append((target, depth + 1, path))
    return list(done.items())


# MAVLink's standard messages, which every dialect includes (common.xml and the files it includes): a
# later file cannot redefine one of the base dialect's (mavgen refuses any dialect that does)
STANDARD_FILES = frozenset({"common.xml", "standard.xml", "minimal.xml"})
MAX_MESSAGES = 1 << 16  # messages of a Dialect, all files together (all.xml: 425; the native table: 2**20)
MAX_ENTRIES = 1 << 16  # entries of one enum, all files together (MAV_CMD: 300; the native summary: 2**20)


class Dialect:
    """Messages and enums from one or more dialect XML files, merged (load: the rules for a definition that
    meets an earlier one)."""

    def __init__(self) -> None:
        self.messages: dict[int, MessageDef] = {}
        self.by_name: dict[str, MessageDef] = {}
        self.enums: dict[str, EnumDef] = {}
        self.files: list[str] = []
        self.standard: frozenset[int] = frozenset()  # ids no later file may redefine (load_dialect: the base's)
        self.warnings: list[str] = []  # one line per definition a later file redefined or could not
        self._entry_names: dict[str, str] = {}  # enum entry name -> its enum

    def load(self, path: str | os.PathLike[str], cache: Path | None = None) -> None:
        """Add every message and enum of `path` and of the files it includes (their parsed XML cached in
        the directory `cache`, if given: mavscope.mavlink.dialect_cache).

        Within the file and its includes a name or id defined twice is refused, as mavgen refuses it
        (dialect_check.duplicates). Against the files loaded before, a definition the same as an earlier
        one (id, name, CRC_EXTRA) is that message; otherwise, each case said in one line of `warnings`:
        a name never changes meaning (a message whose name an earlier message of another id has, an enum
        entry whose name or value an earlier entry has, is not loaded: `-Y COMMAND_LONG` keeps meaning
        message 76); a message id of MAVLink's standard messages (`standard`) keeps its definition; any
        other id takes the later file's definition (a vendor's dialect for its own vehicles), its earlier
        name then naming no message."""
        records = _parse_files(Path(path), cache)
        duplicates(records)
        self.files.append(str(path))
        for file, record in records:
            for m in record["messages"]:
                self._add_message(m, file.name)
            for e in record["enums"]:
                self._merge_enum(e, file.name)

    def _add_message(self, m: list, src: str) -> None:
        mid, name, crc_extra = m[0], m[1], m[2]
        old, named = self.messages.get(mid), self.by_name.get(name)
        if old is not None and old.crc_extra == crc_extra and old.name == name:
            return
        what = f"{src}: message {name} (id {mid})"
        if named is not None and named.id != mid:
            self.warnings.append(f"{what} not loaded: {name} is message id {named.id} of {named.source}")
            return
        if old is not None and mid in self.standard:
            self.warnings.append(f"{what} not loaded: id {mid} is {old.name} of {old.source}, one of MAVLink's "
                                 "standard messages")
            return
        if old is not None:
            self.warnings.append(f"{what} replaces {old.name} of {old.source}")
            self.by_name.pop(old.name, None)
        elif len(self.messages) >= MAX_MESSAGES:
            raise DialectError(f"{src}: cannot load dialect: more than {MAX_MESSAGES:,} messages in all")
        md = _compile_message(m, src)
        self.messages[md.id] = md
        self.by_name[md.name] = md

    def _merge_enum(self, e: list, src: str) -> None:
        name, bitmask, description, new_entries = e
        existing = self.enums.get(name)
        entries = dict(existing.entries) if existing else {}
        for entry_name, value, entry_description, params, param_enums in new_entries:
            old, owner = entries.get(value), self._entry_names.get(entry_name)
            if old is not None and old.name == entry_name:
                continue  # the same entry: the earlier one's description and params are kept
            what = f"{src}: enum entry {name}.{entry_name} = {value} not loaded:"
            if old is not None:
                self.warnings.append(f"{what} {value} is {name}.{old.name} of an earlier dialect")
                continue
            if owner is not None:
                self.warnings.append(f"{what} {entry_name} is an entry of {owner} already")
                continue
            if len(entries) >= MAX_ENTRIES:
                raise DialectError(f"{src}: cannot load dialect: enum {name} has more than {MAX_ENTRIES:,} entries")
            entries[value] = EnumEntry(entry_name, value, entry_description, tuple(map(tuple, params)),
                                       tuple(map(tuple, param_enums)))
            self._entry_names[entry_name] = name
        self.enums[name] = EnumDef(
            name=name,
            bitmask=bitmask or bool(existing and existing.bitmask),
            entries=entries,
            by_name={en.name: en for en in entries.values()},
            description=(existing.description if existing and existing.description else description),
        )

    def enum_value(self, name: str) -> tuple[str, int] | None:
        """Find an enum entry by its name anywhere (MAV_CMD_NAV_RETURN_TO_LAUNCH -> ("MAV_CMD", 20))."""
        for enum in self.enums.values():
            entry = enum.by_name.get(name)
            if entry is not None:
                return enum.name, entry.value
        return None

    def command_param_enum(self, command: int, index: int) -> str:
        """The enum naming the values of param `index` of MAV_CMD `command` ("" where the XML gives none)."""
        enum = self.enums.get("MAV_CMD")
        entry = enum.entries.get(command) if enum else None
        return dict(entry.param_enums).get(index, "") if entry else ""

    def command_params(self, command: int) -> tuple[tuple[int, str, str], ...]:
        """(index, label, units) of the labelled params of MAV_CMD `command`."""
        enum = self.enums.get("MAV_CMD")
        entry = enum.entries.get(command) if enum else None
        return entry.params if entry else ()


def pymavlink_dialect_path(name: str = "all") -> Path:
    """Path of a dialect XML shipped with pymavlink (v2.0 definitions)."""
    import pymavlink

    return Path(pymavlink.__file__).parent / "dialects" / "v20" / f"{name}.xml"


def default_dissectors_dir() -> Path:
    """The `dissectors/` folder whose XML loads automatically: the repository's in a source checkout
    (where users drop their dialects), else the copy a wheel installs inside the package."""
    package = Path(__file__).resolve().parents[1]
    checkout = package.parent / "dissectors"
    return checkout if checkout.is_dir() else package / "dissectors"


_said: set[str] = set()  # the warnings written to stderr by this process outside `warnings_to`
_sink: ContextVar[tuple[Callable[[str], None], set[str]] | None] = ContextVar("dialect_warnings", default=None)


@contextmanager
def warnings_to(say: Callable[[str], None]) -> Iterator[None]:
    """Within the block, the warnings of `load_dialect` go to `say` (the command line's stderr: cli.main),
    each once however often the dialect is loaded."""
    token = _sink.set((say, set()))
    try:
        yield
    finally:
        _sink.reset(token)


def _warn(line: str) -> None:
    sink = _sink.get()
    say, said = sink if sink is not None else (lambda text: sys.stderr.write(f"mavscope: {visible(text)}\n"), _said)
    if line not in said:
        said.add(line)
        say(line)


def load_dialect(
    extra: Iterable[str | os.PathLike[str]] = (),
    *,
    base: str | os.PathLike[str] | None = None,
    dissectors: str | os.PathLike[str] | None = None,
    environ: Mapping[str, str] | None = None,
    warn: Callable[[str], None] | None = None,
) -> Dialect:
    """The default dialect (pymavlink's all.xml), then every XML in `dissectors/`, then `extra` files.
    Each file's parsed XML comes from the cache `environ` (default os.environ) names, where it holds it
    (mavscope.mavlink.dialect_cache.cache_dir: MAVSCOPE_CACHE_DIR, MAVSCOPE_NO_CACHE). The base's messages
    from MAVLink's standard files (STANDARD_FILES) are `standard`. Each of the Dialect's `warnings` (a later
    file's definition that meets an earlier one: Dialect.load) goes to `warn`, by default one line on
    stderr, escaped (that of the command line within `warnings_to`), once."""
    cache = cache_dir(environ)
    folder = Path(dissectors) if dissectors is not None else default_dissectors_dir()
    files = sorted(folder.glob("*.xml")) if folder.is_dir() else []
    extra = list(extra)
    # The default dialect is loaded once per process (a Dialect is never changed once loaded): every command
    # run in one process (batch, the TUI, the tests) would parse it again. Keyed by the files' sizes and times.
    key = None if extra or base is not None or dissectors is not None or environ is not None else (
        str(cache), *((str(f), f.stat().st_size, f.stat().st_mtime_ns) for f in [Path(_base_path()), *files]))
    d = _LOADED.get(key) if key is not None else None
    if d is None:
        d = Dialect()
        d.load(base if base is not None else _base_path(), cache)
        d.standard = frozenset(mid for mid, m in d.messages.items() if m.source in STANDARD_FILES)
        for xml in files:
            d.load(xml, cache)
        for path in extra:
            d.load(path, cache)
        if key is not None:
            _LOADED.clear()  # (one default dialect is kept: a changed file makes another key)
            _LOADED[key] = d
    for line in d.warnings:
        (warn or _warn)(line)
    return d


_LOADED: dict[object, Dialect] = {}


def _base_path() -> Path:
    return pymavlink_dialect_path("all")
