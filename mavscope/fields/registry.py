"""The field registry: every field mavscope shows, filters on or exports, declared once.

In the spirit of Wireshark's `hf_register_info`, each field is one `Field`: its filter name
(`mavlink.seq`), the Wireshark Lua dissector's alias (`mavlink_proto.sequence`), the label the detail
tree shows, its key in the JSON Lines export, its value type and enum, where its bytes lie in a v1
and a v2 frame, and how to get its value out of a `Frame`. The detail tree (`fields.tree`), display
filters (`mavscope.filter`), the JSON export (`output.jsonout`) and hex highlighting (through the
tree's byte ranges) all iterate `FIELDS`, so a name means one thing everywhere.

Payload fields come from the loaded dialect (`MSG.field`, alias `mavlink_proto.MSG_field`);
`FieldRegistry(dialect)` resolves any name to a `Field`, a `PayloadField` or a message. The fields of
the protocols inside byte arrays (`ftp.opcode`, `log.data`...) are declared by `fields.containers`
and registered here with the others.

A field a frame does not have (the signature of an unsigned frame, `udp.port` of a tlog entry,
`COMMAND_LONG.command` of a HEARTBEAT) yields `MISSING`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter

from mavscope.fields import containers
from mavscope.fields.units import companion, companion_name, scale_of, scaled
from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef
from mavscope.mavlink.frame import IFLAG_ENCRYPTION_MASK, EncryptionStatus, Frame, SignatureStatus, signature_status
from mavscope.notes import CODES, frame_codes
from mavscope.wire import HEADER_V1, HEADER_V2, IFLAG_SIGNED, SIGNATURE_LEN


class _Missing:
    __slots__ = ()

    def __repr__(self) -> str:
        return "MISSING"

    def __bool__(self) -> bool:
        return False


MISSING: object = _Missing()

# Value types: how a filter converts literals for comparisons.
INT, FLOAT, STR, IP, BYTES, NONE = "int", "float", "str", "ip", "bytes", "none"

# JSON blocks a field may belong to (None: the top level of a frame's object).
SIGNATURE_BLOCK = "signature"
ENCRYPTION_BLOCK = "encryption"

Getter = Callable[[Frame], object]
Span = Callable[[Frame], "tuple[int, int] | None"]


@dataclass(frozen=True, slots=True)
class Field:
    """One registered field."""

    name: str  # filter name: "mavlink.seq"
    label: str  # detail-tree label: "Packet sequence"
    type: str  # INT, FLOAT, STR, IP, BYTES, NONE (existence only)
    get: Getter  # the value; MISSING where the frame has no such field
    alias: str = ""  # the Wireshark Lua dissector's name
    json_key: str | None = None  # key in the JSON Lines object (in `json_block`); None: not exported
    json_block: str | None = None  # None (top level), SIGNATURE_BLOCK or ENCRYPTION_BLOCK
    json_get: Getter | None = None  # the JSON value where it is not `get`'s (MISSING: key omitted)
    attr: str | None = None  # the Frame attribute holding the value as-is (JSON reads it directly)
    enum: str = ""  # the dialect enum naming its values
    v1: tuple[int, int] | None = None  # (offset, size) in a v1 frame's header
    v2: tuple[int, int] | None = None  # (offset, size) in a v2 frame's header
    span: Span | None = None  # (offset, size) in the frame of a field after the header (CRC, signature)
    choices: tuple[str, ...] = ()  # the values a STR field can take (checked when a filter compiles)
    values: tuple[tuple[int, str], ...] = ()  # names of an INT field's values (Wireshark's value_string)
    multi: bool = False  # the value is a tuple of values (ip.addr): a comparison holds if one does
    description: str = ""

    def position(self, frame: Frame) -> tuple[int, int] | None:
        """Where the field's bytes lie in `frame` as (offset, size), None for a computed field."""
        if self.span is not None:
            return self.span(frame)
        return self.v2 if frame.version == 2 else self.v1


def _attr(name: str) -> Getter:
    return attrgetter(name)


def _v2_only(name: str) -> Getter:
    get = attrgetter(name)
    return lambda f: get(f) if f.version == 2 else MISSING


def _or_missing(get: Getter) -> Getter:
    def g(f: Frame) -> object:
        v = get(f)
        return MISSING if v is None else v
    return g


def _present_if(cond: Callable[[Frame], bool]) -> Getter:
    return lambda f: True if cond(f) else MISSING


# --- transport --------------------------------------------------------------------------------------


def _endpoint(which: str, attr: str, absent: object = MISSING) -> Getter:
    """`attr` of the frame's `which` endpoint (src or dst); `absent` where the frame has none."""
    get = attrgetter(which)

    def g(f: Frame) -> object:
        ep = get(f)
        return absent if ep is None else getattr(ep, attr)
    return g


def _ip_any(f: Frame) -> object:
    vals = tuple(ep.address for ep in (f.src, f.dst) if ep is not None)
    return vals if vals else MISSING


def _port(transport: str, which: str) -> Getter:
    get = attrgetter(which)

    def g(f: Frame) -> object:
        ep = get(f)
        return ep.port if ep is not None and f.transport == transport else MISSING
    return g


def _port_any(transport: str) -> Getter:
    def g(f: Frame) -> object:
        if f.transport != transport:
            return MISSING
        vals = tuple(ep.port for ep in (f.src, f.dst) if ep is not None)
        return vals if vals else MISSING
    return g


# --- signature and encryption -----------------------------------------------------------------------


def _crc_span(f: Frame) -> tuple[int, int] | None:
    return (f.header_len + f.length, 2) if f.crc is not None else None


def _sig_span(offset: int, size: int) -> Span:
    def span(f: Frame) -> tuple[int, int] | None:
        if f.signature is None:
            return None
        return (f.header_len + f.length + 2 + offset, size)
    return span


def _sig(attr: str) -> Getter:
    def g(f: Frame) -> object:
        s = f.signature
        return MISSING if s is None else getattr(s, attr)
    return g


def _sig_value(f: Frame) -> object:
    return MISSING if f.signature is None else f.signature.value.hex()


def _sig_iso(f: Frame) -> object:
    return MISSING if f.signature is None else f.signature.iso_time()


def _sig_status(f: Frame) -> object:
    status = signature_status(f.incompat_flags, f.security)
    return MISSING if status is None else status.value


def _sig_key(f: Frame) -> object:
    sec = f.security
    return MISSING if sec is None or sec.key is None else sec.key


def _sig_skew(f: Frame) -> object:
    """Signature time - capture time, where the security layer judged the frame and the capture has times."""
    s = f.signature
    if s is None or f.security is None or f.time is None:
        return MISSING
    return round(s.unix_time - f.time, 6)


def _enc(attr: str) -> Getter:
    def g(f: Frame) -> object:
        sec = f.security
        enc = None if sec is None else sec.encryption
        if enc is None:
            if attr == "method" and f.encryption_method:
                return f.encryption_method
            return MISSING
        value = getattr(enc, attr)
        if attr == "status":
            return value.value
        return MISSING if value is None or value == "" else value
    return g


def _enc_json(attr: str) -> Getter:
    """JSON of the encryption block: present where the security layer decided something."""
    def g(f: Frame) -> object:
        sec = f.security
        enc = None if sec is None else sec.encryption
        if enc is None:
            return MISSING
        value = getattr(enc, attr)
        if attr == "status":
            return value.value
        if attr == "reason":
            return value if value else MISSING
        return value
    return g


def _note(code: str) -> Getter:
    def g(f: Frame) -> object:
        for n in f.notes:
            if n.code == code:
                return n.message
        return MISSING
    return g


def _build() -> tuple[Field, ...]:
    sig_block, enc_block = SIGNATURE_BLOCK, ENCRYPTION_BLOCK
    fields = [
        # the frame in its capture (top of the JSON object)
        Field("frame.number", "Frame number", INT, _attr("record"), json_key="frame", attr="record",
              description="capture record number (JSON `frame`)"),
        Field("frame.index", "Index in record", INT, _attr("index"), json_key="index", attr="index",
              description="position of the frame within its record"),
        Field("frame.time", "Capture time", FLOAT, _or_missing(_attr("time")), json_key="time", attr="time",
              description="capture time, Unix seconds"),
        Field("frame.transport", "Transport", STR, _attr("transport"), json_key="transport", attr="transport",
              choices=("udp", "tcp", "tlog", "raw"), description="udp, tcp, tlog or raw"),
        Field("frame.src", "Source", STR, _endpoint("src", "text"), json_key="src",
              json_get=_endpoint("src", "text", None), description="source address:port"),
        Field("frame.dst", "Destination", STR, _endpoint("dst", "text"), json_key="dst",
              json_get=_endpoint("dst", "text", None), description="destination address:port"),
        Field("frame.len", "Frame length", INT, lambda f: len(f.raw), description="bytes of the MAVLink frame"),
        # the MAVLink header, in wire order
        Field("mavlink.version", "MAVLink version", INT, _attr("version"), "mavlink_proto.version",
              json_key="version", attr="version", description="MAVLink version (1 or 2)"),
        Field("mavlink.magic", "Magic", INT, lambda f: f.raw[0], "mavlink_proto.magic", v1=(0, 1), v2=(0, 1)),
        Field("mavlink.len", "Payload length", INT, _attr("length"), "mavlink_proto.length", json_key="len",
              attr="length", v1=(1, 1), v2=(1, 1)),
        Field("mavlink.incompat_flags", "Incompatibility flags", INT, _v2_only("incompat_flags"),
              "mavlink_proto.incompatibility_flag", json_key="incompat_flags", attr="incompat_flags", v2=(2, 1)),
        Field("mavlink.compat_flags", "Compatibility flags", INT, _v2_only("compat_flags"),
              "mavlink_proto.compatibility_flag", json_key="compat_flags", attr="compat_flags", v2=(3, 1)),
        Field("mavlink.seq", "Packet sequence", INT, _attr("seq"), "mavlink_proto.sequence", json_key="seq",
              attr="seq", v1=(2, 1), v2=(4, 1)),
        Field("mavlink.sysid", "System id", INT, _attr("sysid"), "mavlink_proto.sysid", json_key="sysid",
              attr="sysid", v1=(3, 1), v2=(5, 1)),
        Field("mavlink.compid", "Component id", INT, _attr("compid"), "mavlink_proto.compid", json_key="compid",
              attr="compid", enum="MAV_COMPONENT", v1=(4, 1), v2=(6, 1)),
        Field("mavlink.msgid", "Message id", INT, _attr("msgid"), "mavlink_proto.msgid", json_key="msgid",
              attr="msgid", v1=(5, 1), v2=(7, 3)),
        Field("mavlink.msgname", "Message", STR, _or_missing(_attr("msgname")), json_key="msgname",
              json_get=_attr("msgname"), description="message name (absent when the id is in no loaded dialect)"),
        Field("mavlink.crc", "CRC", INT, _or_missing(_attr("crc")), "mavlink_proto.crc", json_key="crc",
              attr="crc", span=_crc_span),
        Field("mavlink.crc_status", "CRC status", STR, lambda f: f.crc_status.value, json_key="crc_status",
              attr="crc_status", choices=("ok", "bad", "unchecked", "truncated"), description="CRC verdict"),
        Field("mavlink.payload", "Payload", BYTES, _attr("payload"), description="the payload bytes as on the wire"),
        Field("mavlink.signed", "Signed", NONE, _present_if(lambda f: bool(f.incompat_flags & IFLAG_SIGNED)),
              description="present when incompat flag 0x01 (signed) is set"),
        # the signature block (JSON `signature`)
        Field("signature", "Signature", NONE, _present_if(lambda f: f.signature is not None),
              span=_sig_span(0, SIGNATURE_LEN), description="present on signed frames"),
        Field("signature.link_id", "Link id", INT, _sig("link_id"), "mavlink_proto.signature_link",
              json_key="link_id", json_block=sig_block, span=_sig_span(0, 1)),
        Field("signature.timestamp", "Timestamp", INT, _sig("timestamp"), "mavlink_proto.signature_time",
              json_key="timestamp", json_block=sig_block, span=_sig_span(1, 6)),
        Field("signature.time", "Time", FLOAT, _sig("unix_time"), json_key="time", json_block=sig_block,
              json_get=_sig_iso, description="signature timestamp as Unix seconds (ISO-8601 text in JSON)"),
        Field("signature.value", "Signature", STR, _sig_value, "mavlink_proto.signature_signature",
              json_key="value", json_block=sig_block, span=_sig_span(7, 6)),
        Field("signature.status", "Status", STR, _sig_status, json_key="status", json_block=sig_block,
              choices=tuple(s.value for s in SignatureStatus),
              description="signature verdict (no-key without key material)"),
        Field("signature.key", "Key", STR, _sig_key, json_key="key", json_block=sig_block,
              description="name of the key whose MAC matched"),
        Field("signature.skew", "Skew", FLOAT, _sig_skew, json_key="skew", json_block=sig_block,
              description="signature time minus capture time, seconds (where the security layer ran)"),
        # payload encryption (JSON `encryption`)
        Field("encryption", "Encryption", NONE, _present_if(lambda f: bool(f.incompat_flags & IFLAG_ENCRYPTION_MASK)),
              description="present on frames with an encrypted payload (incompat bits 5-7)"),
        Field("encryption.method", "Method", INT, _enc("method"), json_key="method", json_block=enc_block,
              json_get=_enc_json("method"), description="SecureMAV method (incompat_flags >> 5, 1..7)"),
        Field("encryption.scheme", "Scheme", STR, _enc("scheme"), json_key="scheme", json_block=enc_block,
              json_get=_enc_json("scheme"), description="cipher configured for the method"),
        Field("encryption.status", "Status", STR, _enc("status"), json_key="status", json_block=enc_block,
              json_get=_enc_json("status"), choices=tuple(s.value for s in EncryptionStatus),
              description="what the security layer did with the payload"),
        Field("encryption.reason", "Reason", STR, _enc("reason"), json_key="reason", json_block=enc_block,
              json_get=_enc_json("reason"), description="why decryption failed or was not possible"),
        # transport
        Field("ip.src", "Source address", IP, _endpoint("src", "address"), description="source IP address"),
        Field("ip.dst", "Destination address", IP, _endpoint("dst", "address"), description="destination IP address"),
        Field("ip.addr", "Address", IP, _ip_any, multi=True, description="either IP address"),
        Field("udp.srcport", "UDP source port", INT, _port("udp", "src"), description="UDP source port"),
        Field("udp.dstport", "UDP destination port", INT, _port("udp", "dst"), description="UDP destination port"),
        Field("udp.port", "UDP port", INT, _port_any("udp"), multi=True, description="either UDP port"),
        Field("tcp.srcport", "TCP source port", INT, _port("tcp", "src"), description="TCP source port"),
        Field("tcp.dstport", "TCP destination port", INT, _port("tcp", "dst"), description="TCP destination port"),
        Field("tcp.port", "TCP port", INT, _port_any("tcp"), multi=True, description="either TCP port"),
    ]
    # the protocols inside byte arrays (FTP, LOG_DATA, TUNNEL, SERIAL_CONTROL, ENCAPSULATED_DATA): the
    # tree nests them under their array; not exported to JSON
    for spec in containers.SPECS:
        assert spec.type in (INT, STR, BYTES, NONE), spec
        fields.append(Field(spec.name, spec.label, spec.type, _or_missing(spec.get), span=spec.span,
                            choices=spec.choices, values=spec.values, multi=spec.multi,
                            description=spec.description))
    # expert info: one field per note code a frame can carry (its value is the note's message)
    fields += [Field(f"note.{code}", code, STR, _note(code), description=f"note: {CODES[code].summary}")
               for code in frame_codes()]
    return tuple(fields)


FIELDS: tuple[Field, ...] = _build()
BY_NAME: dict[str, Field] = {f.name: f for f in FIELDS}
# Other spellings of registered names: the Wireshark Lua dissector's, and a few short ones.
ALIASES: dict[str, str] = {f.alias: f.name for f in FIELDS if f.alias} | {"frame.num": "frame.number"}
HEADER: tuple[Field, ...] = tuple(f for f in FIELDS if f.v1 is not None or f.v2 is not None)  # tree order


def field(name: str) -> Field:
    """A registered field by name (KeyError for an unknown one)."""
    return BY_NAME[name]


@dataclass(frozen=True, slots=True)
class PayloadField:
    """A payload field name: `MSG.field` (one message) or a bare `field` (every message that has it); or a
    display-unit companion of a scaled field (`MSG.lat_deg`: fields.units), whose value is the field's divided
    by `divisors[msgid]`."""

    name: str
    defs: dict[int, FieldDef]  # msgid -> the field's definition in that message
    divisors: dict[int, int] | None = None  # a companion: msgid -> the scale's divisor

    @property
    def bare(self) -> bool:
        return "." not in self.name

    def value(self, frame: Frame, fields: dict[str, object] | None) -> object:
        """The field's value in `frame` (decoded `fields`), in the companion's unit; MISSING where it has none."""
        return self.value_at(frame.msgid, frame.msgdef, fields)

    def value_at(self, msgid: int, md: MessageDef | None, fields: dict[str, object] | None) -> object:
        """`value` of a frame of message `msgid` (its definition `md`) whose payload decoded as `fields`."""
        value = payload_value_at(self.defs, msgid, md, fields)
        if self.divisors is None or value is MISSING:
            return value
        return scaled(value, self.divisors[msgid])


def payload_value(defs: dict[int, FieldDef], frame: Frame, fields: dict[str, object] | None) -> object:
    """The value of a payload field in `frame` (decoded `fields`), MISSING where it has none."""
    return payload_value_at(defs, frame.msgid, frame.msgdef, fields)


def payload_value_at(defs: dict[int, FieldDef], msgid: int, md: MessageDef | None,
                     fields: dict[str, object] | None) -> object:
    """`payload_value` of a frame of message `msgid`, defined by `md`."""
    if fields is None:
        return MISSING
    fd = defs.get(msgid)
    if fd is None or md is None or md.name != fd.message:
        return MISSING
    return fields.get(fd.name, MISSING)


def payload_position(frame: Frame, fd: FieldDef) -> tuple[int, int]:
    """(offset, bytes present) of payload field `fd` in `frame`: v2 senders trim trailing zero bytes."""
    base = HEADER_V2 if frame.version == 2 else HEADER_V1
    return base + fd.offset, max(0, min(fd.size, frame.length - fd.offset))


class FieldRegistry:
    """Every name mavscope knows for a dialect: registered fields, aliases, payload fields, message names."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self._bare: dict[str, dict[int, FieldDef]] | None = None
        self._lua: dict[str, FieldDef] | None = None
        self._companions: dict[str, dict[int, tuple[FieldDef, int]]] | None = None

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

    def lookup(self, name: str) -> Field | PayloadField | MessageDef | None:
        """Resolve a name: a registered field (or alias), `MSG.field`, `mavlink_proto.MSG_field`, a message
        name, or a bare payload field; then a bare header name (`crc_status` -> `mavlink.crc_status`)."""
        canonical = ALIASES.get(name, name)
        f = BY_NAME.get(canonical)
        if f is not None:
            return f
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
            if fd is not None:
                return PayloadField(name, {md.id: fd})
            got = companion(md, fname)
            return PayloadField(name, {md.id: got[0]}, {md.id: got[1].divisor}) if got is not None else None
        md = self.dialect.by_name.get(name)
        if md is not None:
            return md
        defs = self._bare_index().get(name)
        if defs:
            return PayloadField(name, defs)
        scaled_defs = self._companion_index().get(name)
        if scaled_defs:
            return PayloadField(name, {m: fd for m, (fd, _) in scaled_defs.items()},
                                {m: d for m, (_, d) in scaled_defs.items()})
        return BY_NAME.get(f"mavlink.{name}")

    def _companion_index(self) -> dict[str, dict[int, tuple[FieldDef, int]]]:
        """Bare companion name -> per message, the scaled field and its divisor."""
        if self._companions is None:
            idx: dict[str, dict[int, tuple[FieldDef, int]]] = {}
            bare = self._bare_index()
            for md in self.dialect.messages.values():
                for fd in md.fields:
                    cname = companion_name(fd)
                    if cname is not None and md.field(cname) is None and cname not in bare:
                        s = scale_of(fd)
                        assert s is not None
                        idx.setdefault(cname, {})[md.id] = (fd, s.divisor)
            self._companions = idx
        return self._companions

    def all_names(self) -> list[str]:
        """Every registered name and alias, every `MSG.field` and message name (for suggestions)."""
        names = list(BY_NAME) + list(ALIASES)
        for md in self.dialect.messages.values():
            names.append(md.name)
            names.extend(fd.filter_name for fd in md.fields)
            names.extend(f"{md.name}.{c}" for c in (companion_name(fd) for fd in md.fields)
                         if c is not None and md.field(c) is None)
        names.extend(self._bare_index())
        names.extend(self._companion_index())
        return names
