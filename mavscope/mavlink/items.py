"""The field registry and the detail tree of a frame.

One registry names every item mavscope shows: header fields (`mavlink.seq`, with the Wireshark Lua
dissector's `mavlink_proto.sequence` as an alias), payload fields (`COMMAND_LONG.command`) and
signature fields. Each tree item carries the registry name, its byte offset and length within the
frame, the raw value and its display text, so the tree, the hex view, JSON and filters agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mavscope.mavlink.dialect import COMMAND_MESSAGES, Dialect, FieldDef, MessageDef
from mavscope.mavlink.frame import HEADER_V1, HEADER_V2, SIGNATURE_LEN, CrcStatus, Frame, decode_payload
from mavscope.mavlink.framing import mcrf4xx


@dataclass(frozen=True, slots=True)
class HeaderField:
    """A header or trailer field: registry name, label, JSON key, Wireshark alias, position per version."""

    name: str
    label: str
    json_key: str
    alias: str
    v1: tuple[int, int] | None  # (offset, size) in a v1 frame; None if absent
    v2: tuple[int, int] | None


HEADER_FIELDS: tuple[HeaderField, ...] = (
    HeaderField("mavlink.magic", "Magic", "magic", "mavlink_proto.magic", (0, 1), (0, 1)),
    HeaderField("mavlink.len", "Payload length", "len", "mavlink_proto.length", (1, 1), (1, 1)),
    HeaderField("mavlink.incompat_flags", "Incompatibility flags", "incompat_flags",
                "mavlink_proto.incompatibility_flag", None, (2, 1)),
    HeaderField("mavlink.compat_flags", "Compatibility flags", "compat_flags",
                "mavlink_proto.compatibility_flag", None, (3, 1)),
    HeaderField("mavlink.seq", "Packet sequence", "seq", "mavlink_proto.sequence", (2, 1), (4, 1)),
    HeaderField("mavlink.sysid", "System id", "sysid", "mavlink_proto.sysid", (3, 1), (5, 1)),
    HeaderField("mavlink.compid", "Component id", "compid", "mavlink_proto.compid", (4, 1), (6, 1)),
    HeaderField("mavlink.msgid", "Message id", "msgid", "mavlink_proto.msgid", (5, 1), (7, 3)),
)
TRAILER_FIELDS: tuple[HeaderField, ...] = (
    HeaderField("mavlink.crc", "CRC", "crc", "mavlink_proto.crc", None, None),
    HeaderField("signature.link_id", "Link id", "link_id", "mavlink_proto.signature_link", None, None),
    HeaderField("signature.timestamp", "Timestamp", "timestamp", "mavlink_proto.signature_time", None, None),
    HeaderField("signature.value", "Signature", "value", "mavlink_proto.signature_signature", None, None),
)
ALIASES: dict[str, str] = {f.alias: f.name for f in HEADER_FIELDS + TRAILER_FIELDS}

# MAV_FRAME values whose x/y are latitude/longitude (degE7 in the *_INT messages).
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11, 17, 18, 19})


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


def _fmt_float(v: float) -> str:
    if math.isnan(v) or math.isinf(v):
        return str(v)
    return f"{v:.7g}"


def format_value(fd: FieldDef, value: object, dialect: Dialect) -> str:
    """Human text for one payload field value: enum names, flags, degrees, units."""
    units = fd.units
    if isinstance(value, list):
        if fd.type in ("uint8_t", "int8_t") and len(value) > 16:
            return bytes(v & 0xFF for v in value).hex(" ")
        return "[" + ", ".join(_fmt_float(v) if isinstance(v, float) else str(v) for v in value) + "]"
    if isinstance(value, str):
        return repr(value)
    if fd.enum and isinstance(value, int):
        enum = dialect.enums.get(fd.enum)
        if enum is not None:
            if enum.bitmask or fd.display == "bitmask":
                flags = enum.flags_of(value)
                return f"0x{value:x} ({' | '.join(flags) if flags else 'none'})"
            name = enum.name_of(value)
            return f"{name} ({value})" if name else f"{value} (unknown {fd.enum})"
    if units == "degE7" and isinstance(value, int):
        return f"{value / 1e7:.7f}° ({value})"
    if fd.display == "bitmask" and isinstance(value, int):
        return f"0x{value:x}"
    text = _fmt_float(value) if isinstance(value, float) else str(value)
    return f"{text} {units}" if units else text


def command_param_label(
    md: MessageDef, fd: FieldDef, fields: dict[str, object], dialect: Dialect
) -> tuple[str, str] | None:
    """(label, units) of param1..7 / x / y / z of a command-carrying message, from MAV_CMD's <param>s."""
    if md.name not in COMMAND_MESSAGES:
        return None
    index = {"param1": 1, "param2": 2, "param3": 3, "param4": 4, "param5": 5, "param6": 6, "param7": 7,
             "x": 5, "y": 6, "z": 7}.get(fd.name)
    command = fields.get("command")
    if index is None or not isinstance(command, int):
        return None
    for i, label, units in dialect.command_params(command):
        if i == index:
            return label, units
    return None


def _payload_value_text(
    md: MessageDef, fd: FieldDef, value: object, fields: dict[str, object], dialect: Dialect
) -> str:
    label = command_param_label(md, fd, fields, dialect)
    if label is not None:
        plabel, punits = label
        frame = fields.get("frame")
        is_int_coord = fd.name in ("x", "y") and md.name in ("COMMAND_INT", "MISSION_ITEM_INT")
        if is_int_coord and isinstance(value, int) and (frame in GLOBAL_FRAMES or frame is None):
            text = f"{value / 1e7:.7f}° ({value})"
        else:
            text = format_value(fd, value, dialect)
            if punits and not fd.units and isinstance(value, float):
                text = f"{text} {punits}"
        return f"{plabel} ({fd.name}): {text}"
    return f"{fd.name}: {format_value(fd, value, dialect)}"


def payload_items(frame: Frame, dialect: Dialect, fields: dict[str, object]) -> tuple[Item, ...]:
    """One item per payload field, in wire order; fields beyond a truncated (v2) payload are marked."""
    md = frame.msgdef
    assert md is not None
    base = frame.header_len
    items = []
    for fd in md.fields:
        value = fields.get(fd.name)
        text = _payload_value_text(md, fd, value, fields, dialect)
        present = max(0, min(fd.size, frame.length - fd.offset))
        if present < fd.size:
            # MAVLink 2 senders trim trailing zero bytes; the receiver restores them.
            text += " [trimmed: zero-filled]" if present == 0 else " [partly trimmed: zero-filled]"
        if fd.extension:
            text += " [extension]"
        items.append(Item(text, fd.filter_name, base + fd.offset, present, value))
    return tuple(items)


def frame_items(frame: Frame, dialect: Dialect, fields: dict[str, object] | None = None) -> tuple[Item, ...]:
    """The detail tree of a frame: header, payload, CRC, signature, notes."""
    v2 = frame.version == 2
    header: list[Item] = []
    values = {
        "magic": f"0x{frame.raw[0]:02x} (MAVLink v{frame.version})",
        "len": str(frame.length),
        "incompat_flags": _flags_text(frame.incompat_flags),
        "compat_flags": f"0x{frame.compat_flags:02x}",
        "seq": str(frame.seq),
        "sysid": str(frame.sysid),
        "compid": _compid_text(frame.compid, dialect),
        "msgid": f"{frame.msgid} ({frame.msgname or 'unknown'})",
    }
    raw_values = {
        "magic": frame.raw[0], "len": frame.length, "incompat_flags": frame.incompat_flags,
        "compat_flags": frame.compat_flags, "seq": frame.seq, "sysid": frame.sysid, "compid": frame.compid,
        "msgid": frame.msgid,
    }
    for hf in HEADER_FIELDS:
        pos = hf.v2 if v2 else hf.v1
        if pos is None:
            continue
        off, size = pos
        size = max(0, min(size, len(frame.raw) - off))
        header.append(Item(f"{hf.label}: {values[hf.json_key]}", hf.name, off, size, raw_values[hf.json_key]))
    hlen = HEADER_V2 if v2 else HEADER_V1
    tree: list[Item] = [
        Item(f"Header (MAVLink v{frame.version})", "mavlink.header", 0, min(hlen, len(frame.raw)), None, tuple(header))
    ]
    plen = max(0, min(frame.length, len(frame.raw) - hlen))
    if fields is None:
        fields = decode_payload(frame)
    if frame.msgdef is not None and fields is not None:
        tree.append(Item(f"Payload: {frame.msgdef.name} ({frame.length} bytes)", "mavlink.payload", hlen, plen,
                         None, payload_items(frame, dialect, fields)))
    else:
        why = ("unknown message id" if frame.msgdef is None else
               "encrypted" if frame.encryption_method else "cannot be decoded")
        tree.append(Item(f"Payload: {frame.length} bytes ({why})", "mavlink.payload", hlen, plen, frame.payload))
    crc_off = hlen + frame.length
    if frame.crc is not None:
        expected = ""
        md = frame.msgdef
        if md is not None and frame.crc_status is CrcStatus.BAD:
            calc = mcrf4xx(md.crc_extra_byte, mcrf4xx(frame.raw[1:crc_off]))
            expected = f", should be 0x{calc:04x}"
        tree.append(Item(f"CRC: 0x{frame.crc:04x} [{frame.crc_status.value}{expected}]", "mavlink.crc", crc_off, 2,
                         frame.crc))
    else:
        tree.append(Item("CRC: [missing: frame truncated]", "mavlink.crc", crc_off, 0, None, generated=True))
    sig = frame.signature
    if sig is not None:
        so = crc_off + 2
        tree.append(Item(
            f"Signature: link {sig.link_id}, {sig.iso_time()}",
            "signature", so, SIGNATURE_LEN, None,
            (
                Item(f"Link id: {sig.link_id}", "signature.link_id", so, 1, sig.link_id),
                Item(f"Timestamp: {sig.timestamp} ({sig.iso_time()})", "signature.timestamp", so + 1, 6, sig.timestamp),
                Item(f"Signature: {sig.value.hex()}", "signature.value", so + 7, 6, sig.value.hex()),
                _signature_status_item(frame, so),
            ),
        ))
    sec = frame.security
    if sec is not None and sec.encryption is not None:
        enc = sec.encryption
        text = f"Encryption: method {enc.method}"
        if enc.scheme:
            text += f" ({enc.scheme})"
        text += f" [{enc.status.value}{': ' + enc.reason if enc.reason else ''}]"
        tree.append(Item(text, "encryption.status", hlen, plen, enc.status.value, generated=True))
    for n in frame.notes:
        tree.append(Item(f"[{n.severity.value}] {n.message}", f"note.{n.code}", 0, 0, n.code, generated=True))
    return tuple(tree)


def _signature_status_item(frame: Frame, offset: int) -> Item:
    sec = frame.security
    if sec is None or sec.signature_status is None:
        return Item("Status: no-key (no key supplied)", "signature.status", offset, 0, "no-key", generated=True)
    text = f"Status: {sec.signature_status.value}"
    if sec.key:
        text += f" (key {sec.key})"
    if sec.reason:
        text += f": {sec.reason}"
    return Item(text, "signature.status", offset, 0, sec.signature_status.value, generated=True)


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
    return f"{compid} ({name})" if name else str(compid)


def flatten(items: tuple[Item, ...]) -> list[Item]:
    """Depth-first list of every item (for hex highlighting and lookups by byte)."""
    out: list[Item] = []
    for it in items:
        out.append(it)
        out.extend(flatten(it.children))
    return out


def item_at(items: tuple[Item, ...], byte: int) -> Item | None:
    """The most specific item covering frame byte `byte`."""
    best: Item | None = None
    for it in flatten(items):
        if it.length and it.offset <= byte < it.offset + it.length:
            if best is None or it.length <= best.length:
                best = it
    return best
