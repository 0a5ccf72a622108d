"""Event sources built on the parameter and object analyses: each runs that analysis's tracker over the
frames (the one `mavscope params` and `mavscope objects` run) and turns its records into events.

`ParamEvents` turns the parameter timeline into `param` events at the end (a set is open until its
answer or the confirmation window has passed; the timeline is sorted by frame); `FileEvents` makes a
`file` event of each object as the object tracker finishes it, taking it at once so the tracker lets go
of its bytes, and one of each FTP operation that moved no object at the end.
"""

from __future__ import annotations

from collections.abc import Iterable

from mavscope.analysis.events.model import FILE, PARAM, Event, Fields, addr
from mavscope.analysis.objects import (
    FTP_LIST,
    FTP_READ,
    FTP_WRITE,
    IMAGE,
    SCRIPT_PATHS,
    TRACKED_MESSAGES,
    FtpOperation,
    ObjectRecord,
    ObjectTracker,
    party,
)
from mavscope.analysis.params import MESSAGES, ParamChange, ParamTracker, json_value, value_text
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.visible import quoted

FTP_MESSAGE = "FILE_TRANSFER_PROTOCOL"  # read by both trackers from the frame's bytes, never decoded
_VERBS = {FTP_READ: "FTP read", FTP_WRITE: "FTP write", FTP_LIST: "FTP listing"}
SIGNATURES = {"unsigned": "unsigned", "valid": "validly signed", "no-key": "signed, not checked without the key",
              "invalid": "with an invalid signature", "replay": "with a replayed signature"}


def shown(text: str) -> str:
    """A name or path from the capture as the event text shows it: in quotes where it is not printable, as
    it is (whoever shows the text escapes it, once: mavscope.visible)."""
    return text if text.isprintable() and "\\" not in text else quoted(text)


def _answer(c: ParamChange, latency_ms: float | None) -> str:
    if c.confirmed:
        return "confirmed" + (f" by {c.ack}" if c.ack else "") + \
            (f" in {latency_ms:.1f} ms" if latency_ms is not None else "")
    if c.confirmed is False:
        if c.ack:
            return f"refused: {c.ack}"
        return f"not confirmed: {addr(c.component)} reports {value_text(c.reported)}"
    return "not confirmed: no answer in the capture"


def param_event(c: ParamChange) -> Event:
    """The event of one entry of the parameter timeline: a set with its answer, or a change with what explains
    it (a REQUEST_DATA_STREAM setting a stream rate) or that nothing in the capture explains it."""
    was = f" (was {value_text(c.previous)})" if c.previous is not None else ""
    guard = ""
    if c.security is not None:
        signed = SIGNATURES.get(c.signature, c.signature)
        guard = f"; security-relevant ({c.security}, {signed})" + (f": turns off {c.disables}" if c.disables else "")
    latency = None
    if c.confirm_time is not None and c.time is not None:
        latency = round((c.confirm_time - c.time) * 1000, 3)
    details: dict[str, object] = {
        "what": c.kind, "name": c.name, "value": json_value(c.value), "previous": json_value(c.previous),
        "confirmed": c.confirmed, "confirm_frame": c.confirm_frame, "reported": json_value(c.reported),
        "retries": c.retries, "ack": c.ack, "latency_ms": latency, "security": c.security, "disables": c.disables,
        "source": c.source, "link": c.link, "signature": c.signature, "explanation": c.explanation,
        "cause_frame": c.cause_frame}
    if c.kind == "set":
        via = "" if c.source == "PARAM_SET" else f" with {c.source}"
        retries = f", retried {c.retries} time{'s' if c.retries > 1 else ''}" if c.retries else ""
        text = (f"{addr(c.sender)} sets {addr(c.component)} {shown(c.name)} = {value_text(c.value)}{was}{via}"
                f"{retries}: {_answer(c, latency)}{guard}")
        return Event(c.time, c.frame, PARAM, c.sender, text, c.component, details)
    why = f": {c.explanation}" if c.explanation else " with no set to explain it"
    text = f"{addr(c.component)} {shown(c.name)} changed to {value_text(c.value)}{was}{why} ({c.source}){guard}"
    return Event(c.time, c.frame, PARAM, c.sender, text, None, details)


class ParamEvents:
    """Every entry of the parameter timeline (`mavscope params`): PARAM_SET, PARAM_EXT_SET and param.pck
    written over FTP, each with its answer (the value confirmed, or the one reported instead, or none),
    retries and the PARAM_EXT_ACK; values that changed, with the REQUEST_DATA_STREAM that set them (stream
    rates) or with nothing in the capture to explain them. Values are decoded as the component carries them
    (ArduPilot's C cast, PX4's bytes)."""

    # the messages the tracker decodes: decoded once by the log and handed on (FTP it reads from the bytes)
    wants = MESSAGES - {FTP_MESSAGE}

    def __init__(self) -> None:
        self.tracker = ParamTracker()

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        self.tracker.feed(f, fields)
        return ()

    def finish(self) -> Iterable[Event]:
        return [param_event(c) for c in self.tracker.finish().timeline]


def _label(r: ObjectRecord) -> str:
    if r.path is not None:
        return shown(r.path)
    if r.kind == IMAGE:
        d = r.details
        return f"{r.name} ({d.get('type_name', '?')} {d.get('width', '?')}x{d.get('height', '?')})"
    return "(its open is not in the capture)" if r.kind in _VERBS else r.name


def _state(r: ObjectRecord) -> str:
    if r.kind == FTP_LIST:
        amount = f"{r.received:,} entries"
    else:
        amount = f"{r.size:,} bytes" if r.complete or r.received == r.size else f"{r.received:,} of {r.size:,} bytes"
        if r.announced_size is not None and r.announced_size != r.size:
            amount += f" ({r.announced_size:,} announced)"
    if r.complete:
        return amount + ", complete"
    missing = sum(b - a for a, b in r.gaps)
    if missing:
        return amount + f", incomplete: {missing:,} {r.gap_unit} missing in {len(r.gaps)} gap(s)"
    return amount + ", incomplete: " + (r.problems[0] if r.problems else "its end is not in the capture")


def object_event(r: ObjectRecord) -> Event:
    """The event of one object moved over the link, dated by its first frame."""
    verb = _VERBS.get(r.kind)
    what = f"{verb} {_label(r)}" if verb else _label(r)
    runs = r.kind == FTP_WRITE and r.path is not None and SCRIPT_PATHS.search(r.path) is not None
    text = f"{party(r.sender)} -> {party(r.receiver)} {what}: {_state(r)}" + \
        ("; a file the vehicle runs as code" if runs else "")
    details: dict[str, object] = {
        "what": "object", "object": r.kind, "number": r.number, "path": r.path, "name": r.name,
        "direction": r.direction, "size": r.size, "announced_size": r.announced_size, "received": r.received,
        "complete": r.complete, "gaps": [list(g) for g in r.gaps], "gap_unit": r.gap_unit, "sha256": r.sha256,
        "last_frame": r.last_frame, "frame_count": r.frame_count, "signed_frames": r.signed_frames,
        "runs_as_code": runs}
    for key in ("session", "log_id"):
        if key in r.details:
            details[key] = r.details[key]
    sender = r.sender or r.receiver or (0, 0)
    return Event(r.start, r.first_frame, FILE, sender, text, r.receiver if r.sender else None, details)


def operation_event(op: FtpOperation) -> Event:
    """The event of an FTP request that moved no object (a removal, a rename, a refused open...)."""
    path = "" if op.path is None else f" {shown(op.path)}"
    if op.new_path is not None:
        path += f" -> {shown(op.new_path)}"
    detail = f" ({op.detail})" if op.detail else ""
    text = f"{party(op.client)} -> {party(op.server)} {op.opcode}{path}: {op.result or 'no answer'}{detail}"
    return Event(op.time, op.frame, FILE, op.client, text, op.server,
                 {"what": "operation", "opcode": op.opcode, "path": op.path, "new_path": op.new_path,
                  "result": op.result, "reply_frame": op.reply_frame, "detail": op.detail})


class FileEvents:
    """Every object the object reconstruction rebuilds (`mavscope objects`: files read and written over
    MAVLink FTP, directory listings, logs, images), as it finishes, and every FTP operation that moved no
    object (removals, renames, directories, CRCs, refused opens) with the server's answer."""

    wants = TRACKED_MESSAGES - {FTP_MESSAGE}  # LOG_* and image messages, decoded once and handed on

    def __init__(self, dialect: Dialect) -> None:
        self.tracker = ObjectTracker()
        self.tracker.use_dialect(dialect)

    def _taken(self) -> list[Event]:
        return [object_event(r) for r in self.tracker.take()]  # take(): the tracker drops the bytes

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        self.tracker.feed(f, fields)
        return self._taken() if self.tracker.finished_waiting else ()

    def finish(self) -> Iterable[Event]:
        log = self.tracker.finish()
        return self._taken() + [operation_event(op) for op in log.operations]
