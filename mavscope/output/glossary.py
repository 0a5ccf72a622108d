"""`read -G fields` and `read -G values`: the field registry as tshark's glossaries print theirs.

`tshark -G fields` prints one line per protocol (`P`, name, abbreviation) and per field (`F`, name,
abbreviation, type, protocol, description, base, bitmask), tab-separated; `tshark -G values` one line per
named value of an integer field (`V`, field, value, name). The same here for every name a filter, `-e` or
the JSON can use: the frame, MAVLink header, signature, encryption, transport, container and note fields
of the registry (their protocol is the part before the first dot), then every payload field of the loaded
dialect under its message (`MSG.field`, protocol `mavlink`, type from its MAVLink type: `FT_UINT8` ...
`FT_FLOAT`, `FT_STRING` for a char array; an array's description says its length), their units in the
description. Values: the named values of a registry field (`ftp.opcode`), the entries of the enum a header
field or payload field names (`mavlink.compid`'s MAV_COMPONENT, `HEARTBEAT.type`'s MAV_TYPE; a bitmask
enum's entries are its bits, printed in hex as tshark prints a bitmask's). Every name and description from
a dialect is escaped (`visible`): a dialect file cannot write to the terminal or break a line.
"""

from __future__ import annotations

from collections.abc import Iterator

from mavscope.fields.registry import BYTES, FIELDS, FLOAT, INT, IP, NONE, STR
from mavscope.mavlink.dialect import Dialect, FieldDef
from mavscope.visible import visible

FT = {INT: "FT_UINT32", FLOAT: "FT_DOUBLE", STR: "FT_STRING", IP: "FT_IPv4", BYTES: "FT_BYTES", NONE: "FT_NONE"}
PROTOCOLS = {"frame": "Frame", "mavlink": "MAVLink", "signature": "MAVLink 2 signature",
             "encryption": "Payload encryption", "ip": "Internet Protocol", "udp": "User Datagram Protocol",
             "tcp": "Transmission Control Protocol", "note": "Expert information"}
_MAVLINK_FT = {"uint8_t": "FT_UINT8", "int8_t": "FT_INT8", "uint16_t": "FT_UINT16", "int16_t": "FT_INT16",
               "uint32_t": "FT_UINT32", "int32_t": "FT_INT32", "uint64_t": "FT_UINT64", "int64_t": "FT_INT64",
               "float": "FT_FLOAT", "double": "FT_DOUBLE", "char": "FT_STRING", "uint8_t_mavlink_version": "FT_UINT8"}


def _line(*cells: str) -> str:
    return "\t".join(visible(c) for c in cells)


def _base(ft: str, bitmask: bool = False) -> str:
    if ft.startswith(("FT_UINT", "FT_INT")):
        return "BASE_HEX" if bitmask else "BASE_DEC"
    return "BASE_NONE"


def _payload_ft(fd: FieldDef) -> str:
    return _MAVLINK_FT.get(fd.type, "FT_BYTES")


def _payload_blurb(fd: FieldDef) -> str:
    words = [fd.description.strip()]
    if fd.array_length and fd.type != "char":
        words.append(f"(array of {fd.array_length})")
    if fd.units:
        words.append(f"[{fd.units}]")
    if fd.extension:
        words.append("(extension field)")
    return " ".join(w for w in words if w)


def fields_lines(dialect: Dialect) -> Iterator[str]:
    """The lines of `read -G fields`."""
    seen: list[str] = []
    for f in FIELDS:
        proto = f.name.partition(".")[0]
        if proto not in seen:
            seen.append(proto)
    for proto in seen:
        yield _line("P", PROTOCOLS.get(proto, proto.upper()), proto)
    for f in FIELDS:
        ft = FT[f.type]
        yield _line("F", f.label, f.name, ft, f.name.partition(".")[0], f.description, _base(ft), "0x0")
    for md in sorted(dialect.messages.values(), key=lambda m: m.id):
        for fd in md.fields:
            ft = _payload_ft(fd)
            yield _line("F", f"{md.name} {fd.name}", fd.filter_name, ft, "mavlink", _payload_blurb(fd),
                        _base(ft, fd.display == "bitmask"), "0x0")


def values_lines(dialect: Dialect) -> Iterator[str]:
    """The lines of `read -G values`."""
    enums = dialect.enums
    for f in FIELDS:
        for value, name in f.values:
            yield _line("V", f.name, str(value), name)
        enum = enums.get(f.enum) if f.enum else None
        if enum is not None:
            for value, entry in sorted(enum.entries.items()):
                yield _line("V", f.name, f"0x{value:x}" if enum.bitmask else str(value), entry.name)
    for md in sorted(dialect.messages.values(), key=lambda m: m.id):
        for fd in md.fields:
            enum = enums.get(fd.enum) if fd.enum else None
            if enum is None:
                continue
            for value, entry in sorted(enum.entries.items()):
                yield _line("V", fd.filter_name, f"0x{value:x}" if enum.bitmask else str(value), entry.name)
