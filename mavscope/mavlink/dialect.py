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
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from mavscope.errors import DialectError
from mavscope.mavlink.dialect_cache import Record, cache_dir, record_of

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
    xml_order: tuple[str, ...] = ()  # field names in XML order (pymavlink's `fieldnames`; CSV columns)

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
    """A char array's value. Same rule as pymavlink: trailing NULs go, undecodable bytes are shown escaped."""
    return raw.rstrip(b"\x00").decode("utf-8", errors="backslashreplace")


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

    # (name, first index in the flat tuple, count, kind) with kind: 0 scalar, 1 string, 2 array
    plan: list[tuple[str, int, int, int]] = []
    i = 0
    for f in fields:
        if f.type == "char":
            plan.append((f.name, i, 1, 1))
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
        xml_order=tuple(xml_order),
    )


def _parse_files(root: Path, cache: Path | None = None) -> list[tuple[Path, Record]]:
    """The records of `root` and, breadth first, of every file it includes (from the cache in `cache`, a
    directory, or parsed by pymavlink)."""
    done: dict[Path, Record] = {}
    queue = [root.resolve()]
    while queue:
        path = queue.pop(0)
        if path in done:
            continue
        if not path.is_file():
            raise DialectError(f"{path}: dialect file not found")
        record = record_of(path, cache)
        done[path] = record
        queue.extend((path.parent / inc).resolve() for inc in record["include"])
    return list(done.items())


class Dialect:
    """Messages and enums from one or more dialect XML files, merged; later files override earlier ones."""

    def __init__(self) -> None:
        self.messages: dict[int, MessageDef] = {}
        self.by_name: dict[str, MessageDef] = {}
        self.enums: dict[str, EnumDef] = {}
        self.files: list[str] = []
        self.overrides: list[str] = []  # "MSG (id) from A replaced by B" for each redefinition

    def load(self, path: str | os.PathLike[str], cache: Path | None = None) -> None:
        """Add every message and enum of `path` and of the files it includes (their parsed XML cached in
        the directory `cache`, if given: mavscope.mavlink.dialect_cache)."""
        records = _parse_files(Path(path), cache)
        self.files.append(str(path))
        for file, record in records:
            src = file.name
            for m in record["messages"]:
                mid, name, crc_extra = m[0], m[1], m[2]
                old = self.messages.get(mid)
                if old is not None:
                    if old.crc_extra == crc_extra and old.name == name:
                        continue
                    self.overrides.append(f"{old.name} ({mid}) from {old.source} replaced by {name} from {src}")
                    self.by_name.pop(old.name, None)
                md = _compile_message(m, src)
                self.messages[md.id] = md
                self.by_name[md.name] = md
            for e in record["enums"]:
                self._merge_enum(e)

    def _merge_enum(self, e: list) -> None:
        name, bitmask, description, new_entries = e
        existing = self.enums.get(name)
        entries = dict(existing.entries) if existing else {}
        for entry_name, value, entry_description, params, param_enums in new_entries:
            entries[value] = EnumEntry(entry_name, value, entry_description, tuple(map(tuple, params)),
                                       tuple(map(tuple, param_enums)))
        self.enums[name] = EnumDef(
            name=name,
            bitmask=bitmask or bool(existing and existing.bitmask),
            entries=entries,
            by_name={en.name: en for en in entries.values()},
            description=description,
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


def load_dialect(
    extra: Iterable[str | os.PathLike[str]] = (),
    *,
    base: str | os.PathLike[str] | None = None,
    dissectors: str | os.PathLike[str] | None = None,
    environ: Mapping[str, str] | None = None,
) -> Dialect:
    """The default dialect (pymavlink's all.xml), then every XML in `dissectors/`, then `extra` files.
    Each file's parsed XML comes from the cache `environ` (default os.environ) names, where it holds it
    (mavscope.mavlink.dialect_cache.cache_dir: MAVSCOPE_CACHE_DIR, MAVSCOPE_NO_CACHE)."""
    cache = cache_dir(environ)
    d = Dialect()
    d.load(base if base is not None else pymavlink_dialect_path("all"), cache)
    folder = Path(dissectors) if dissectors is not None else default_dissectors_dir()
    if folder.is_dir():
        for xml in sorted(folder.glob("*.xml")):
            d.load(xml, cache)
    for path in extra:
        d.load(path, cache)
    return d
