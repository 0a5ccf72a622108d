"""Value accessors for the field registry: registry name -> function(frame) -> value.

The names are the registry's (mavscope.mavlink.items): the header fields `mavlink.*` with their
Wireshark Lua aliases `mavlink_proto.*`, the signature fields, `MSG.field` for payload fields. This
module adds the names that are computed rather than read from the frame's bytes (`mavlink.version`,
`mavlink.crc_status`, `frame.number`, `ip.src`, ...) and, for every name, how to get its value out of
a Frame. Display filters (mavscope.analysis.filter), statistics and the TUI look names up here, so
one name means the same thing everywhere.

A field that a frame does not have (the signature of an unsigned frame, `udp.port` of a tlog entry,
`COMMAND_LONG.command` of a HEARTBEAT) yields `MISSING`.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Callable
from dataclasses import dataclass

from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef
from mavscope.mavlink.frame import Frame, SignatureStatus
from mavscope.mavlink.items import ALIASES, HEADER_FIELDS, TRAILER_FIELDS
from mavscope.notes import CODES


class _Missing:
    __slots__ = ()

    def __repr__(self) -> str:
        return "MISSING"

    def __bool__(self) -> bool:
        return False


MISSING: object = _Missing()

# Value types of fields: how literals are converted for comparisons.
INT, FLOAT, STR, IP, BYTES, NONE = "int", "float", "str", "ip", "bytes", "none"


@dataclass(frozen=True, slots=True)
class FrameField:
    """A field whose value comes from the frame record (no payload decoding needed)."""

    name: str
    type: str  # INT, FLOAT, STR, IP, BYTES, NONE (existence only)
    description: str
    get: Callable[[Frame], object]  # returns MISSING where the frame has no such field
    choices: tuple[str, ...] = ()  # the values a STR field can take (checked at filter compile time)
    multi: bool = False  # the value is a tuple of values (ip.addr, udp.port): a comparison holds if any does
    enum: str = ""  # the dialect enum that names this field's values (mavlink.compid: MAV_COMPONENT)


def _endpoint(ep: str | None) -> tuple[str, int] | None:
    if not ep:
        return None
    host, _, port = ep.rpartition(":")
    try:
        return host.strip("[]"), int(port)
    except ValueError:
        return None


def _ip(which: int) -> Callable[[Frame], object]:
    def get(f: Frame) -> object:
        ep = _endpoint(f.src if which == 0 else f.dst)
        if ep is None:
            return MISSING
        try:
            return ipaddress.ip_address(ep[0])
        except ValueError:
            return MISSING
    return get


def _ip_any(f: Frame) -> object:
    vals = tuple(v for v in (_ip(0)(f), _ip(1)(f)) if v is not MISSING)
    return vals if vals else MISSING


def _port(transport: str, which: int) -> Callable[[Frame], object]:
    def get(f: Frame) -> object:
        if f.transport != transport:
            return MISSING
        ep = _endpoint(f.src if which == 0 else f.dst)
        return ep[1] if ep is not None else MISSING
    return get


def _port_any(transport: str) -> Callable[[Frame], object]:
    src, dst = _port(transport, 0), _port(transport, 1)

    def get(f: Frame) -> object:
        vals = tuple(v for v in (src(f), dst(f)) if v is not MISSING)
        return vals if vals else MISSING
    return get


def _sig(attr: str) -> Callable[[Frame], object]:
    def get(f: Frame) -> object:
        s = f.signature
        return MISSING if s is None else getattr(s, attr)
    return get


def _sig_status(f: Frame) -> object:
    if f.signature is None:
        sec = f.security
        # A frame flagged signed but cut before its signature still has a verdict.
        if sec is not None and sec.signature_status is not None:
            return sec.signature_status.value
        return MISSING
    sec = f.security
    if sec is None or sec.signature_status is None:
        return SignatureStatus.NO_KEY.value
    return sec.signature_status.value


def _sig_key(f: Frame) -> object:
    sec = f.security
    return MISSING if sec is None or sec.key is None else sec.key


def _enc(attr: str) -> Callable[[Frame], object]:
    def get(f: Frame) -> object:
        sec = f.security
        enc = None if sec is None else sec.encryption
        if enc is None:
            if attr == "method" and f.encryption_method:
                return f.encryption_method
            return MISSING
        value = getattr(enc, attr)
        if attr == "status":
            return value.value
        return MISSING if value is None else value
    return get


def _v2_only(get: Callable[[Frame], object]) -> Callable[[Frame], object]:
    return lambda f: get(f) if f.version == 2 else MISSING


def _note(code: str) -> Callable[[Frame], object]:
    def get(f: Frame) -> object:
        for n in f.notes:
            if n.code == code:
                return n.message
        return MISSING
    return get


def _present_if(cond: Callable[[Frame], bool]) -> Callable[[Frame], object]:
    return lambda f: True if cond(f) else MISSING


def _build_frame_fields() -> dict[str, FrameField]:
    out: list[FrameField] = []
    header_get: dict[str, Callable[[Frame], object]] = {
        "mavlink.magic": lambda f: f.raw[0],
        "mavlink.len": lambda f: f.length,
        "mavlink.incompat_flags": _v2_only(lambda f: f.incompat_flags),
        "mavlink.compat_flags": _v2_only(lambda f: f.compat_flags),
        "mavlink.seq": lambda f: f.seq,
        "mavlink.sysid": lambda f: f.sysid,
        "mavlink.compid": lambda f: f.compid,
        "mavlink.msgid": lambda f: f.msgid,
        "mavlink.crc": lambda f: MISSING if f.crc is None else f.crc,
        "signature.link_id": _sig("link_id"),
        "signature.timestamp": _sig("timestamp"),
        "signature.value": lambda f: MISSING if f.signature is None else f.signature.value.hex(),
    }
    for hf in HEADER_FIELDS + TRAILER_FIELDS:
        typ = STR if hf.name == "signature.value" else INT
        enum = "MAV_COMPONENT" if hf.name == "mavlink.compid" else ""
        out.append(FrameField(hf.name, typ, hf.label, header_get[hf.name], enum=enum))
    out += [
        FrameField("mavlink.version", INT, "MAVLink version (1 or 2)", lambda f: f.version),
        FrameField("mavlink.msgname", STR, "message name (absent when the id is in no loaded dialect)",
                   lambda f: MISSING if f.msgdef is None else f.msgdef.name),
        FrameField("mavlink.crc_status", STR, "CRC verdict", lambda f: f.crc_status.value,
                   choices=("ok", "bad", "unchecked", "truncated")),
        FrameField("mavlink.payload", BYTES, "the payload bytes as on the wire", lambda f: f.payload),
        FrameField("mavlink.signed", NONE, "present when incompat flag 0x01 (signed) is set",
                   _present_if(lambda f: bool(f.incompat_flags & 1))),
        FrameField("signature", NONE, "present on signed frames", _present_if(lambda f: f.signature is not None)),
        FrameField("signature.time", FLOAT, "signature timestamp as Unix seconds", _sig("unix_time")),
        FrameField("signature.status", STR, "signature verdict (no-key without key material)", _sig_status,
                   choices=tuple(s.value for s in SignatureStatus)),
        FrameField("signature.key", STR, "name of the key whose MAC matched", _sig_key),
        FrameField("encryption", NONE, "present on frames with an encrypted payload (incompat bits 5-7)",
                   _present_if(lambda f: bool(f.encryption_method))),
        FrameField("encryption.method", INT, "SecureMAV method (incompat_flags >> 5, 1..7)", _enc("method")),
        FrameField("encryption.scheme", STR, "cipher configured for the method", _enc("scheme")),
        FrameField("encryption.status", STR, "what the security layer did with the payload", _enc("status"),
                   choices=("decrypted", "no-key", "failed")),
        FrameField("frame.number", INT, "capture record number (JSON `frame`)", lambda f: f.record),
        FrameField("frame.index", INT, "position of the frame within its record", lambda f: f.index),
        FrameField("frame.time", FLOAT, "capture time, Unix seconds",
                   lambda f: MISSING if f.time is None else f.time),
        FrameField("frame.len", INT, "bytes of the MAVLink frame", lambda f: len(f.raw)),
        FrameField("frame.transport", STR, "udp, tcp, tlog or raw", lambda f: f.transport,
                   choices=("udp", "tcp", "tlog", "raw")),
        FrameField("ip.src", IP, "source IP address", _ip(0)),
        FrameField("ip.dst", IP, "destination IP address", _ip(1)),
        FrameField("ip.addr", IP, "either IP address", _ip_any, multi=True),
        FrameField("udp.srcport", INT, "UDP source port", _port("udp", 0)),
        FrameField("udp.dstport", INT, "UDP destination port", _port("udp", 1)),
        FrameField("udp.port", INT, "either UDP port", _port_any("udp"), multi=True),
        FrameField("tcp.srcport", INT, "TCP source port", _port("tcp", 0)),
        FrameField("tcp.dstport", INT, "TCP destination port", _port("tcp", 1)),
        FrameField("tcp.port", INT, "either TCP port", _port_any("tcp"), multi=True),
    ]
    for code in CODES:
        out.append(FrameField(f"note.{code}", STR, f"note: {CODES[code].summary}", _note(code)))
    return {f.name: f for f in out}


FRAME_FIELDS: dict[str, FrameField] = _build_frame_fields()
# The Wireshark Lua dissector's header names, and a few short spellings.
FIELD_ALIASES: dict[str, str] = dict(ALIASES) | {
    "mavlink_proto.version": "mavlink.version",
    "frame.num": "frame.number",
}


@dataclass(frozen=True, slots=True)
class PayloadField:
    """A payload field name: `MSG.field` (one message) or a bare `field` (every message that has it)."""

    name: str
    defs: dict[int, FieldDef]  # msgid -> the field's definition in that message

    @property
    def bare(self) -> bool:
        return "." not in self.name


def payload_value(defs: dict[int, FieldDef], frame: Frame, fields: dict[str, object] | None) -> object:
    """The value of a payload field in `frame` (decoded `fields`), MISSING where it has none."""
    if fields is None:
        return MISSING
    fd = defs.get(frame.msgid)
    if fd is None or frame.msgdef is None or frame.msgdef.name != fd.message:
        return MISSING
    return fields.get(fd.name, MISSING)


class FieldRegistry:
    """Every name mavscope knows for a dialect: frame fields, aliases, payload fields, message names."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self._bare: dict[str, dict[int, FieldDef]] | None = None
        self._lua: dict[str, FieldDef] | None = None

    def _bare_index(self) -> dict[str, dict[int, FieldDef]]:
        if self._bare is None:
            idx: dict[str, dict[int, FieldDef]] = {}
            for md in self.dialect.messages.values():
                for fd in md.fields:
                    idx.setdefault(fd.name, {})[md.id] = fd
            self._bare = idx
        return self._bare

    def _lua_index(self) -> dict[str, FieldDef]:
        if self._lua is None:
            self._lua = {fd.wireshark_name: fd for md in self.dialect.messages.values() for fd in md.fields}
        return self._lua

    def message(self, name: str) -> MessageDef | None:
        return self.dialect.by_name.get(name)

    def lookup(self, name: str) -> FrameField | PayloadField | MessageDef | None:
        """Resolve a name: frame field (or alias), `MSG.field`, `mavlink_proto.MSG_field`, a message name,
        or a bare payload field; then a bare header name (`crc_status` -> `mavlink.crc_status`)."""
        canonical = FIELD_ALIASES.get(name, name)
        ff = FRAME_FIELDS.get(canonical)
        if ff is not None:
            return ff
        if canonical.startswith("mavlink_proto."):
            fd = self._lua_index().get(canonical)
            if fd is not None:
                owner = self.dialect.by_name[fd.message]
                return PayloadField(fd.filter_name, {owner.id: fd})
            return None
        if "." in name:
            msg, _, fname = name.partition(".")
            md = self.dialect.by_name.get(msg)
            if md is None:
                return None
            fd = md.field(fname)
            return PayloadField(name, {md.id: fd}) if fd is not None else None
        md = self.dialect.by_name.get(name)
        if md is not None:
            return md
        defs = self._bare_index().get(name)
        if defs:
            return PayloadField(name, defs)
        ff = FRAME_FIELDS.get(f"mavlink.{name}")
        return ff

    def all_names(self) -> list[str]:
        """Every frame-field name and alias, every `MSG.field` and message name (for suggestions)."""
        names = list(FRAME_FIELDS) + list(FIELD_ALIASES)
        for md in self.dialect.messages.values():
            names.append(md.name)
            names.extend(fd.filter_name for fd in md.fields)
        names.extend(self._bare_index())
        return names
