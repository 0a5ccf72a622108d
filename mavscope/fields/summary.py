"""The Info column of a frame: its message name, key fields and the verdicts that are not ok.

The packet list of the TUI, the summary lines of `read` and `live`, and anything else that lists
frames one per line use this one text. It is shown as it is: every word a capture or a dialect chose in it
is escaped here (`visible`: message, field and enum names; string values with `repr`, `visible` in quotes;
the inner protocol's paths with `repr` too), as the native summary writer's table holds them.
"""

from __future__ import annotations

from weakref import WeakKeyDictionary

from mavscope.fields.containers import info as container_info
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import IFLAG_ENCRYPTION_MASK, CrcStatus, Frame, SignatureStatus, decode_payload
from mavscope.mavlink.semantics import (
    COMMAND_MESSAGES,
    COMMAND_PARAM_INDEX,
    DEGE7,
    INT_COORDINATE_MESSAGES,
    command_param,
    command_param_name,
    float_text,
    message_label,
    param_shown,
)
from mavscope.visible import visible
from mavscope.wire import IFLAG_SIGNED

# The fields a summary line shows per message (default: the first few scalar fields).
SUMMARY_FIELDS: dict[str, tuple[str, ...]] = {
    "HEARTBEAT": ("type", "autopilot", "base_mode", "system_status"),
    "COMMAND_LONG": ("command", "param1", "target_system", "target_component", "confirmation"),
    "COMMAND_INT": ("command", "target_system", "target_component", "frame", "x", "y", "z"),
    "COMMAND_ACK": ("command", "result"),
    "MISSION_ITEM_INT": ("seq", "command", "frame", "x", "y", "z"),
    "MISSION_ITEM": ("seq", "command", "frame", "x", "y", "z"),
    "MISSION_COUNT": ("count", "target_system", "mission_type"),
    "MISSION_REQUEST_INT": ("seq", "target_system", "mission_type"),
    "MISSION_REQUEST": ("seq", "target_system", "mission_type"),
    "MISSION_ACK": ("type", "target_system", "mission_type"),
    "STATUSTEXT": ("severity", "text"),
    "GLOBAL_POSITION_INT": ("lat", "lon", "relative_alt"),
    "GPS_RAW_INT": ("fix_type", "lat", "lon", "satellites_visible"),
    "ATTITUDE": ("roll", "pitch", "yaw"),
    "SYS_STATUS": ("voltage_battery", "battery_remaining", "drop_rate_comm"),
    "PARAM_VALUE": ("param_id", "param_value", "param_index"),
    "PARAM_SET": ("param_id", "param_value"),
    "SETUP_SIGNING": ("target_system", "initial_timestamp"),
}
_MAX_DEFAULT = 4
CONTAINER_MESSAGES = frozenset({"FILE_TRANSFER_PROTOCOL"})  # their Info is the inner protocol's
# STATUSTEXT: a chunk of a long text (id not 0) says which ("[chunk 1 of id 7]"): the events join them
# (analysis/events/statustext.py). The containers' Info is Python's (the native writer hands their frames
# back), and a STATUSTEXT's where its `id` is not 0 (PYTHON_IF: message -> the field that decides)
PYTHON_INFO = CONTAINER_MESSAGES
PYTHON_IF = {"STATUSTEXT": "id"}


# How a summary shows one field: by its name, an enum's names, degE7 as degrees, or by the value's type
# (FLOAT32: a `float` field, the shortest text that reads back as the same float32; a double's repr).
PLAIN, ENUM, DEGREES, FLOAT32 = 0, 1, 2, 3
_Plan = tuple[tuple[str, int, dict[int, str]], ...]
_PLANS: WeakKeyDictionary[Dialect, dict[int, tuple[MessageDef, _Plan]]] = WeakKeyDictionary()


def summary_plan(md: MessageDef, dialect: Dialect) -> _Plan:
    """(name, how, enum names) for the fields the summary of `md` shows: worked out once per message (the
    native summary writer compiles the same plan, mavscope/native/summary.py)."""
    cache = _PLANS.get(dialect)
    if cache is None:
        cache = _PLANS[dialect] = {}
    hit = cache.get(md.id)
    if hit is not None and hit[0] is md:
        return hit[1]
    names = SUMMARY_FIELDS.get(md.name) or tuple(
        f.name for f in md.fields if not f.array_length or f.type == "char"
    )[:_MAX_DEFAULT]
    plan: list[tuple[str, int, dict[int, str]]] = []
    for name in names:
        fd = md.field(name)
        if fd is None:
            continue
        enum = dialect.enums.get(fd.enum) if fd.enum else None
        if fd.type == "float":  # (whatever a dialect says of it: the native writer goes by the wire type)
            plan.append((name, FLOAT32, {}))
        elif enum is not None and not (enum.bitmask or fd.display == "bitmask"):
            plan.append((name, ENUM, {v: e.name for v, e in enum.entries.items()}))
        elif fd.units == "degE7" or (name in ("x", "y") and md.name in INT_COORDINATE_MESSAGES):
            plan.append((name, DEGREES, {}))
        else:
            plan.append((name, PLAIN, {}))
    result = tuple(plan)
    cache[md.id] = (md, result)
    return result


def _short(name: str, how: int, names: dict[int, str], value: object) -> str:
    """One field as the summary shows it: `name=value`, the dialect's names escaped (`visible`), a string
    value as `repr` writes it."""
    name = visible(name)
    if how == ENUM and isinstance(value, int):
        text = names.get(value)
        if text:
            return f"{name}={visible(text)}"
    elif how == DEGREES and isinstance(value, int):
        return f"{name}={value / DEGE7:.7f}"
    if isinstance(value, float):  # (mavlink/floats.py: 30.48, not 30.4799995)
        return f"{name}={float_text(value, how == FLOAT32)}"
    if isinstance(value, str):
        return f"{name}={value!r}"
    if isinstance(value, list):
        return f"{name}=[{len(value)}]"
    return f"{name}={value}"


def summary_info(frame: Frame, dialect: Dialect, fields: dict[str, object] | None = None) -> str:
    """The "Info" column: message name and its key fields, plus the verdicts that are not ok."""
    md = frame.msgdef
    parts: list[str] = []
    if md is None:
        parts.append(message_label(frame.msgid, None))
    else:
        parts.append(visible(md.name))
        if fields is None:
            fields = decode_payload(frame)
        inner = container_info(frame) if md.name in CONTAINER_MESSAGES else None
        if inner is not None:
            parts.append(inner)  # (its paths as `repr` writes them: fields/containers/ftp.py summary)
        elif fields is not None:
            plan = summary_plan(md, dialect)
            if md.name in COMMAND_MESSAGES:  # a parameter its MAV_CMD entry leaves unlabelled: shown if not 0
                command = fields.get("command")
                plan = tuple(p for p in plan if p[0] not in COMMAND_PARAM_INDEX or param_shown(
                    (command_param(dialect, md.name, p[0], command) or ("",))[0], fields.get(p[0])))
            parts.extend(_short(name, how, names, fields.get(name)) for name, how, names in plan)
            if md.name == "STATUSTEXT" and fields.get("id"):
                parts.append(f"[chunk {fields.get('chunk_seq')} of id {fields.get('id')}]")
            if md.name in COMMAND_MESSAGES and "param1" in fields:  # the value's name where the XML gives one
                named = command_param_name(dialect, fields.get("command"), 1, fields["param1"])  # type: ignore[arg-type]
                if named is not None:
                    parts = [f"param1={visible(named)}" if p.startswith("param1=") else p for p in parts]
        elif frame.encryption_method:
            parts.append(f"[encrypted, method {frame.encryption_method}]")
    if frame.crc_status is not CrcStatus.OK:
        parts.append(f"[CRC {frame.crc_status.value}]")
    if frame.incompat_flags & ~(IFLAG_SIGNED | IFLAG_ENCRYPTION_MASK):
        parts.append(f"[unknown incompat flags 0x{frame.incompat_flags:02x}]")
    if any(n.code == "skipped-bytes" for n in frame.notes):
        parts.append("[after skipped bytes]")
    if any(n.code == "hidden-frame" for n in frame.notes):
        parts.append("[hidden: MAVLink's C library reads it]")
    if any(n.code == "split-frame" for n in frame.notes):
        parts.append("[split over datagrams: the receivers read it whole]")
    status = frame.signature_status
    verdict = "" if status in _UNREMARKED else f"signature {status.value}"  # type: ignore[union-attr]
    if frame.signature is not None:
        parts.append(f"[signed link {frame.signature.link_id}{', ' + verdict if verdict else ''}]")
    elif verdict:
        parts.append(f"[{verdict}]")
    return " ".join(parts)


# The signature verdicts a summary leaves unsaid: none (unsigned), valid, and no-key (no key was given, so
# every signed frame is); an invalid, replayed or truncated signature is said (`read --key` shows it). The
# native summary writer writes only frames whose signature is valid or unjudged (it hands the others back).
_UNREMARKED = frozenset({None, SignatureStatus.VALID, SignatureStatus.NO_KEY})


RECORDS_SHOWN = 8  # records of a reassembled frame its heading names (a datagram may come in thousands)


def frame_heading(f: Frame) -> str:
    """The first line of a frame's detail (`read -V`, the TUI's tree): where the frame is."""
    text = f"Frame {f.number}: {len(f.raw)} bytes, {f.transport}"
    if f.src:
        text += f" {f.src} → {f.dst}"
    if f.offset is not None:
        text += f", file offset {f.offset}"
    if f.span:
        more = len(f.span) - RECORDS_SHOWN
        text += f", reassembled from records {', '.join(map(str, f.span[:RECORDS_SHOWN]))}" + (
            f" and {more} more, to record {f.span[-1]}" if more > 0 else "")
    return text
