"""The detail tree of a frame, built from the field registry.

Every item carries its registry name, its byte offset and length within the frame, the raw value and
its display text, so the tree, the hex view (which highlights an item's bytes), JSON and filters agree.
Header, CRC and signature items come from `registry.FIELDS` (label, byte position, value); payload
items from the dialect's field definitions, with enum names, bitmask flags, degE7 as degrees, units,
and for command-carrying messages the parameter labels of the command (Hold, Accept Radius, ... for
NAV_WAYPOINT). A container array (FILE_TRANSFER_PROTOCOL.payload, LOG_DATA.data...) shows a summary and
nests the fields `fields.containers` finds in it.

Labels are shown as they are (`read -V`, the TUI's tree): the words a dialect or a capture chose in them
are escaped as they are built (`visible`: field, enum, message and component names, units, a command's
parameter labels, notes; string values with `repr`, which is `visible` in quotes).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from mavscope.fields import containers
from mavscope.fields.registry import FIELDS, HEADER, Field, field, payload_position
from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef, char_tail, is_text
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload, plaintext_payload
from mavscope.mavlink.framing import mcrf4xx
from mavscope.mavlink.semantics import (
    COMMAND_PARAM_INDEX,
    INT_COORDINATE_MESSAGES,
    command_param,
    command_param_name,
    degrees_text,
    float_text,
    is_global,
)
from mavscope.visible import visible
from mavscope.wire import HEADER_V1, HEADER_V2, SIGNATURE_LEN


@dataclass(frozen=True, slots=True)
class Item:
    """One node of the detail tree."""

    label: str  # what the tree shows: "Packet sequence: 42"
    name: str  # registry / filter name: "mavlink.seq", "COMMAND_LONG.param1"
    offset: int  # byte offset within the frame
    length: int  # bytes covered (0 for generated items)
    value: object = None
    children: tuple[Item, ...] = ()
    generated: bool = False  # computed by mavscope, not on the wire (Wireshark's [brackets])


def _fmt_float(v: float, fd: FieldDef) -> str:
    """A float field's value: the shortest text that reads back as the same float32 (double: repr)."""
    return float_text(v, fd.type != "double")


def format_value(fd: FieldDef, value: object, dialect: Dialect) -> str:
    """Human text for one payload field value: enum names, flags, degrees, units (the dialect's words
    escaped, a string as `repr` writes it)."""
    units = visible(fd.units) if fd.units else fd.units
    if isinstance(value, list):
        if fd.type in ("uint8_t", "int8_t") and len(value) > 16:
            return bytes(v & 0xFF for v in value).hex(" ")
        return "[" + ", ".join(_fmt_float(v, fd) if isinstance(v, float) else str(v) for v in value) + "]"
    if isinstance(value, str):
        return repr(value)
    if fd.enum and isinstance(value, int):
        enum = dialect.enums.get(fd.enum)
        if enum is not None:
            if enum.bitmask or fd.display == "bitmask":
                flags = enum.flags_of(value)
                return f"0x{value:x} ({visible(' | '.join(flags)) if flags else 'none'})"
            name = enum.name_of(value)
            return f"{visible(name)} ({value})" if name else f"{value} (unknown {visible(fd.enum)})"
    if units == "degE7" and isinstance(value, int):
        return degrees_text(value)
    if fd.display == "bitmask" and isinstance(value, int):
        return f"0x{value:x}"
    text = _fmt_float(value, fd) if isinstance(value, float) else str(value)
    return f"{text} {units}" if units and not (isinstance(value, float) and math.isnan(value)) else text


def _payload_value_text(
    md: MessageDef, fd: FieldDef, value: object, fields: dict[str, object], dialect: Dialect
) -> str:
    label = command_param(dialect, md.name, fd.name, fields.get("command"))
    if label is not None:
        plabel, punits = visible(label[0]), visible(label[1] or "")
        frame = fields.get("frame")
        is_int_coord = fd.name in ("x", "y") and md.name in INT_COORDINATE_MESSAGES
        if is_int_coord and isinstance(value, int) and (frame is None or is_global(frame)):  # type: ignore[arg-type]
            text = degrees_text(value)
        else:
            text = format_value(fd, value, dialect)
            index = COMMAND_PARAM_INDEX.get(fd.name, 0)
            name = command_param_name(dialect, fields.get("command"), index, value)  # type: ignore[arg-type]
            if name is not None:
                text = f"{visible(name)} ({text})"
            elif punits and not fd.units and isinstance(value, float) and not math.isnan(value):
                text = f"{text} {punits}"
        return f"{plabel} ({visible(fd.name)}): {text}"
    return f"{visible(fd.name)}: {format_value(fd, value, dialect)}"


def _container_item(node: containers.Node) -> Item:
    return Item(node.label, node.name, node.offset, node.length, node.value,
                tuple(_container_item(n) for n in node.children), node.generated)


def _char_tail_items(frame: Frame, fd: FieldDef, offset: int, present: int) -> tuple[Item, ...]:
    """The bytes of char array `fd` after the NUL that ends its string (the `char-after-nul` note), as an
    item over them: they are on the wire (the hex view shows them) but no part of the value."""
    payload = plaintext_payload(frame)
    raw = b"" if payload is None else payload[fd.offset : fd.offset + present]
    tail = char_tail(raw)
    if not tail:
        return ()
    start = raw.find(0) + 1
    hidden = raw[start : start + tail]
    return (Item(f"[note] {tail} byte{'s' if tail > 1 else ''} after the NUL that ends the string (not part of its "
                 f"value): {hidden!r}", "note.char-after-nul", offset + start, tail, hidden),)


def payload_items(frame: Frame, dialect: Dialect, fields: dict[str, object]) -> tuple[Item, ...]:
    """One item per payload field, in wire order; fields beyond a truncated (v2) payload are marked. A
    container (FILE_TRANSFER_PROTOCOL.payload, LOG_DATA.data...) shows a summary, its fields nested; a char
    array's bytes after the NUL that ends its string are an item under it."""
    md = frame.msgdef
    assert md is not None
    items = []
    for fd in md.fields:
        if fd.extension and frame.version == 1:
            continue  # a MAVLink 1 frame has no extension fields: they are not on the wire, not trimmed
        value = fields.get(fd.name)
        sub = containers.subtree(frame, fd) if fd.array_length else None
        if sub is None:
            text = _payload_value_text(md, fd, value, fields, dialect)
            children: tuple[Item, ...] = ()
        else:
            text = f"{visible(fd.name)}: {sub[0]}"  # (the container's summary escapes its words)
            children = tuple(_container_item(n) for n in sub[1])
        offset, present = payload_position(frame, fd)
        if fd.type == "char" and is_text(fd):
            children = _char_tail_items(frame, fd, offset, present)
        if present < fd.size:
            # MAVLink 2 senders trim trailing zero bytes; the receiver restores them.
            text += " [trimmed: zero-filled]" if present == 0 else " [partly trimmed: zero-filled]"
        if fd.extension:
            text += " [extension]"
        items.append(Item(text, fd.filter_name, offset, present, value, children))
    return tuple(items)


# --- header --------------------------------------------------------------------------------------------


def _flags_text(flags: int) -> str:
    parts = []
    if flags & 0x01:
        parts.append("SIGNED")
    if flags & 0xE0:
        parts.append(f"ENCRYPTED method {flags >> 5}")
    if flags & 0x1E:
        parts.append(f"unknown 0x{flags & 0x1E:02x}")
    return f"0x{flags:02x}" + (f" ({', '.join(parts)})" if parts else "")


def _compid_text(compid: int, dialect: Dialect) -> str:
    enum = dialect.enums.get("MAV_COMPONENT")
    name = enum.name_of(compid) if enum else None
    return f"{compid} ({visible(name)})" if name else str(compid)


# How the tree shows a header field's value (default: the number).
_HEADER_TEXT: dict[str, Callable[[Frame, Dialect], str]] = {
    "mavlink.magic": lambda f, d: f"0x{f.raw[0]:02x} (MAVLink v{f.version})",
    "mavlink.incompat_flags": lambda f, d: _flags_text(f.incompat_flags),
    "mavlink.compat_flags": lambda f, d: f"0x{f.compat_flags:02x}",
    "mavlink.compid": lambda f, d: _compid_text(f.compid, d),
    "mavlink.msgid": lambda f, d: f"{f.msgid} ({visible(f.msgname) if f.msgname else 'unknown'})",
}


def _header_item(hf: Field, frame: Frame, dialect: Dialect) -> Item | None:
    pos = hf.position(frame)
    if pos is None:
        return None
    off, size = pos
    value = hf.get(frame)
    show = _HEADER_TEXT.get(hf.name)
    text = show(frame, dialect) if show is not None else str(value)
    return Item(f"{hf.label}: {text}", hf.name, off, max(0, min(size, len(frame.raw) - off)), value)


# --- CRC, signature, encryption ------------------------------------------------------------------------


def _crc_item(frame: Frame, crc_off: int) -> Item:
    crc = field("mavlink.crc")
    if frame.crc is None:
        return Item(f"{crc.label}: [missing: frame truncated]", crc.name, crc_off, 0, None, generated=True)
    expected = ""
    md = frame.msgdef
    if md is not None and frame.crc_status is CrcStatus.BAD:
        calc = mcrf4xx(md.crc_extra_byte, mcrf4xx(frame.raw[1:crc_off]))
        expected = f", should be 0x{calc:04x}"
    off, size = crc.position(frame)  # type: ignore[misc]  # a frame with a CRC has its position
    return Item(f"{crc.label}: 0x{frame.crc:04x} [{frame.crc_status.value}{expected}]", crc.name, off, size,
                frame.crc)


def _signature_status_item(frame: Frame, offset: int) -> Item:
    sf = field("signature.status")
    sec = frame.security
    if sec is None or sec.signature_status is None:
        return Item(f"{sf.label}: no-key (no key supplied)", sf.name, offset, 0, "no-key", generated=True)
    text = f"{sf.label}: {sec.signature_status.value}"
    if sec.key:
        text += f" (key {visible(sec.key)})"
    if sec.reason is not None:
        text += f": {sec.reason_text}"
    return Item(text, sf.name, offset, 0, sec.signature_status.value, generated=True)


_SIGNATURE_TEXT: dict[str, Callable[[Frame], str]] = {
    "signature.link_id": lambda f: str(f.signature.link_id),  # type: ignore[union-attr]
    "signature.timestamp": lambda f: f"{f.signature.timestamp} ({f.signature.iso_time()})",  # type: ignore[union-attr]
    "signature.value": lambda f: f.signature.value.hex(),  # type: ignore[union-attr]
}
_SIGNATURE_FIELDS = tuple(f for f in FIELDS if f.name in _SIGNATURE_TEXT)


def _signature_item(frame: Frame, crc_off: int) -> Item | None:
    sig = frame.signature
    if sig is None:
        return None
    so = crc_off + 2
    children = []
    for sf in _SIGNATURE_FIELDS:
        off, size = sf.position(frame)  # type: ignore[misc]  # signed: every signature field has bytes
        children.append(Item(f"{sf.label}: {_SIGNATURE_TEXT[sf.name](frame)}", sf.name, off, size, sf.get(frame)))
    children.append(_signature_status_item(frame, so))
    return Item(f"Signature: link {sig.link_id}, {sig.iso_time()}", "signature", so, SIGNATURE_LEN, None,
                tuple(children))


def _encryption_item(frame: Frame, hlen: int, plen: int) -> Item | None:
    sec = frame.security
    if sec is None or sec.encryption is None:
        return None
    enc = sec.encryption
    text = f"Encryption: method {enc.method}"
    if enc.scheme:
        text += f" ({enc.scheme})"
    text += f" [{enc.status.value}{': ' + visible(enc.reason) if enc.reason else ''}]"
    return Item(text, "encryption.status", hlen, plen, enc.status.value, generated=True)


def frame_items(frame: Frame, dialect: Dialect, fields: dict[str, object] | None = None) -> tuple[Item, ...]:
    """The detail tree of a frame: header, payload, CRC, signature, encryption, notes."""
    header = tuple(it for it in (_header_item(hf, frame, dialect) for hf in HEADER) if it is not None)
    hlen = HEADER_V2 if frame.version == 2 else HEADER_V1
    tree: list[Item] = [
        Item(f"Header (MAVLink v{frame.version})", "mavlink.header", 0, min(hlen, len(frame.raw)), None, header)
    ]
    plen = max(0, min(frame.length, len(frame.raw) - hlen))
    if fields is None:
        fields = decode_payload(frame)
    if frame.msgdef is not None and fields is not None:
        tree.append(Item(f"Payload: {visible(frame.msgdef.name)} ({frame.length} bytes)", "mavlink.payload", hlen, plen,
                         None, payload_items(frame, dialect, fields)))
    else:
        why = ("unknown message id" if frame.msgdef is None else
               "encrypted" if frame.encryption_method else "cannot be decoded")
        tree.append(Item(f"Payload: {frame.length} bytes ({why})", "mavlink.payload", hlen, plen, frame.payload))
    crc_off = hlen + frame.length
    tree.append(_crc_item(frame, crc_off))
    for extra in (_signature_item(frame, crc_off), _encryption_item(frame, hlen, plen)):
        if extra is not None:
            tree.append(extra)
    for n in frame.notes:
        tree.append(Item(f"[{n.severity.value}] {visible(n.message)}", f"note.{n.code}", 0, 0, n.code, generated=True))
    return tuple(tree)


def flatten(items: tuple[Item, ...]) -> list[Item]:
    """Depth-first list of every item (for hex highlighting and lookups by byte)."""
    out: list[Item] = []
    for it in items:
        out.append(it)
        out.extend(flatten(it.children))
    return out
