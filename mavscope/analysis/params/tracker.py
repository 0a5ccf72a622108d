"""The parameter timeline in one pass over the frames, with bounded state.

Values come from PARAM_VALUE and PARAM_EXT_VALUE (a component reporting its parameter), from the
`@PARAM/param.pck` files a client read over MAVLink FTP (the object reconstruction rebuilds them, `pck`
decodes them), and from PARAM_EXT_ACK; requests to change them from PARAM_SET and PARAM_EXT_SET.

A set is confirmed by the first report of the same parameter from its target system within
`CONFIRM_WINDOW` seconds (the protocol's answer to PARAM_SET is the PARAM_VALUE it triggers; QGroundControl
and MAVProxy wait about as long before giving up): `confirmed` is True when that report carries the
value set, False when it carries another (the vehicle refused or clamped it), None when none came. A
PARAM_EXT_SET is answered by PARAM_EXT_ACK (PARAM_ACK_IN_PROGRESS waits for the final one). The same set
again before its answer is a retry. A report whose value differs from the component's last one without a
set to explain it is a "change" (a set from another link, a vehicle that changed it itself, a reboot); a
change of a stream-rate parameter that a REQUEST_DATA_STREAM set (`streams.py`) names that request.
"""

from __future__ import annotations

from collections import Counter, OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass

from mavscope.analysis.objects import FTP_READ, FTP_WRITE, Limits, ObjectRecord, ObjectTracker
from mavscope.analysis.objects.model import int_field
from mavscope.analysis.params import pck
from mavscope.analysis.params.export import param_findings
from mavscope.analysis.params.missions import MESSAGES as MISSION_MESSAGES
from mavscope.analysis.params.missions import MissionRequests
from mavscope.analysis.params.model import Addr, Component, Param, ParamChange, ParamLog
from mavscope.analysis.params.security import category, disables
from mavscope.analysis.params.streams import MAX_KEYS, StreamRequests
from mavscope.analysis.params.values import (
    BYTEWISE,
    C_CAST,
    Value,
    field_bytes,
    from_ext_field,
    from_float_field,
    json_value,
    same,
)
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.notes import pop_newest

CONFIRM_WINDOW = 5.0  # seconds after the set's last transmission
MAX_COMPONENTS = 64
MAX_NAMES = 65_536  # per component
MAX_TIMELINE = 100_000
MAX_PENDING = 4096
MAV_AUTOPILOT_PX4, MAV_AUTOPILOT_INVALID, MAV_TYPE_GCS = 12, 8, 6
CAP_BYTEWISE, CAP_C_CAST = 16, 131072  # MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE, _C_CAST
PARAM_ACK_ACCEPTED, PARAM_ACK_IN_PROGRESS = 0, 3
ACK_NAMES = {0: "PARAM_ACK_ACCEPTED", 1: "PARAM_ACK_VALUE_UNSUPPORTED", 2: "PARAM_ACK_FAILED",
             3: "PARAM_ACK_IN_PROGRESS"}
MESSAGES = frozenset({"PARAM_VALUE", "PARAM_SET", "PARAM_EXT_VALUE", "PARAM_EXT_SET", "PARAM_EXT_ACK", "HEARTBEAT",
                      "AUTOPILOT_VERSION", "FILE_TRANSFER_PROTOCOL", "REQUEST_DATA_STREAM"}) | MISSION_MESSAGES


@dataclass
class _Entry:
    """A timeline entry while it can still change (a set awaiting its answer)."""

    time: float | None
    frame: int
    kind: str
    source: str
    sender: Addr
    component: Addr
    name: str
    value: Value
    previous: Value | None
    type: int | None
    link: str
    signature: str
    confirmed: bool | None = None
    confirm_frame: int | None = None
    reported: Value | None = None
    retries: int = 0
    ack: str | None = None
    confirm_time: float | None = None
    last: float | None = None  # time of the last transmission (sets)
    cause_frame: int | None = None
    explanation: str | None = None

    def freeze(self) -> ParamChange:
        return ParamChange(self.time, self.frame, self.kind, self.source, self.sender, self.component, self.name,
                           self.value, self.previous, self.type, self.link, self.signature, self.confirmed,
                           self.confirm_frame, self.reported, self.retries, category(self.name),
                           disables(self.name, self.value), self.ack, self.confirm_time, self.cause_frame,
                           self.explanation)


def _link(f: Frame) -> str:
    return f.src.text if f.src is not None else f.transport


def _verdict(f: Frame) -> str:
    status = f.signature_status
    return "unsigned" if status is None else status.value


def _list(a: Addr | None) -> list[int] | None:
    return None if a is None else [a[0], a[1]]



def _name(fields: dict[str, object]) -> str:
    v = fields.get("param_id", "")
    return v if isinstance(v, str) else str(v)


class ParamTracker:
    def __init__(self, limits: Limits | None = None) -> None:
        self.objects = ObjectTracker(limits, ftp_paths=pck.is_param_pck, ftp_only=True)
        self.components: dict[Addr, Component] = {}
        self.encodings: dict[int, tuple[str, str]] = {}  # sysid -> (encoding, basis)
        self.pending: OrderedDict[tuple[int, str], _Entry] = OrderedDict()  # (target sysid, name) -> set
        self.timeline: list[_Entry] = []
        self.ftp_links: dict[Addr, str] = {}  # FTP party -> the link of its last frame
        self.ftp: list[dict[str, object]] = []
        self.given_up: Counter[str] = Counter()
        self.now: float | None = None
        self.streams = StreamRequests()
        self.missions = MissionRequests()

    # -- frames --------------------------------------------------------------------------------------

    def feed(self, f: Frame, fields: dict[str, object] | None = None) -> None:
        """`fields`: the frame's payload where the caller has decoded it already (so it is not decoded twice)."""
        md = f.msgdef
        if md is None or f.crc_status is not CrcStatus.OK:
            self.objects.feed(f)
            return
        if f.time is not None:
            self.now = f.time
        name = md.name
        if name == "FILE_TRANSFER_PROTOCOL":
            self.ftp_links[(f.sysid, f.compid)] = _link(f)
            self.objects.feed(f)
            if self.objects.finished_waiting:
                for rec in self.objects.take():
                    self._pck(rec)
            return
        self.objects.feed(f)
        if name not in MESSAGES:
            return
        if fields is None:
            fields = decode_payload(f)
        if fields is None:
            return
        if name == "HEARTBEAT":
            autopilot, mav_type = int_field(fields, "autopilot"), int_field(fields, "type")
            if autopilot != MAV_AUTOPILOT_INVALID and mav_type != MAV_TYPE_GCS and \
                    self.encodings.get(f.sysid, ("", ""))[1] != "AUTOPILOT_VERSION":
                enc = BYTEWISE if autopilot == MAV_AUTOPILOT_PX4 else C_CAST
                self.encodings[f.sysid] = (enc, "HEARTBEAT")
        elif name == "AUTOPILOT_VERSION":
            caps = int_field(fields, "capabilities")
            if caps & CAP_BYTEWISE:
                self.encodings[f.sysid] = (BYTEWISE, "AUTOPILOT_VERSION")
            elif caps & CAP_C_CAST:
                self.encodings[f.sysid] = (C_CAST, "AUTOPILOT_VERSION")
        elif name == "PARAM_VALUE":
            raw = field_bytes(f, "param_value")
            if raw is not None:
                self.param_value((f.sysid, f.compid), f.record, f.time, _link(f), _verdict(f), _name(fields), raw,
                                 int_field(fields, "param_type"), int_field(fields, "param_count"))
        elif name == "PARAM_EXT_VALUE":
            raw = field_bytes(f, "param_value")
            if raw is not None:
                ptype = int_field(fields, "param_type")
                comp = self._component((f.sysid, f.compid))
                if comp is not None:
                    comp.announced = int_field(fields, "param_count")
                self._report_frame(f, _name(fields), from_ext_field(raw, ptype), ptype, "PARAM_EXT_VALUE")
        elif name in ("PARAM_SET", "PARAM_EXT_SET"):
            raw = field_bytes(f, "param_value")
            if raw is not None:
                ptype = int_field(fields, "param_type")
                target = (int_field(fields, "target_system"), int_field(fields, "target_component"))
                value = (self._decode(target[0], raw, ptype)[0] if name == "PARAM_SET"
                         else from_ext_field(raw, ptype))
                self._set(f, target, _name(fields), value, ptype, name)
        elif name == "PARAM_EXT_ACK":
            self._ext_ack(f, fields)
        elif name == "REQUEST_DATA_STREAM":
            self.streams.feed(f.record, fields)
        elif name in MISSION_MESSAGES:
            self.missions.feed(f.record, name, fields)

    def param_value(self, addr: Addr, record: int, when: float | None, link: str, verdict: str, name: str,
                    raw: bytes, ptype: int, count: int) -> None:
        """A PARAM_VALUE with a good CRC from component `addr` in frame `record` (`raw`: the 4 bytes of its
        `param_value`), its `link` and signature `verdict` as `feed` names them. `feed` gives every one here;
        so does the export's native source, from its payload columns, without a Frame."""
        value, basis = self._decode(addr[0], raw, ptype)
        comp = self._component(addr)
        if comp is not None:
            comp.announced = count
            if comp.encoding is None or basis != "values":
                comp.encoding, comp.encoding_basis = self._encoding(addr[0], raw, ptype)
        self._report(addr, addr, record, when, link, verdict, name, value, ptype, "PARAM_VALUE")

    def _decode(self, sysid: int, raw: bytes, ptype: int) -> tuple[Value, str]:
        known = self.encodings.get(sysid)
        value, _enc = from_float_field(raw, ptype, known[0] if known else None)
        return value, (known[1] if known else "values")

    def _encoding(self, sysid: int, raw: bytes, ptype: int) -> tuple[str | None, str]:
        known = self.encodings.get(sysid)
        if known is not None:
            return known
        _v, enc = from_float_field(raw, ptype, None)
        return (enc, "values") if enc == BYTEWISE else (None, "")

    def _component(self, addr: Addr) -> Component | None:
        comp = self.components.get(addr)
        if comp is None:
            if len(self.components) >= MAX_COMPONENTS:
                self.given_up[f"components beyond the first {MAX_COMPONENTS} were not followed"] += 1
                return None
            comp = self.components[addr] = Component(addr)
        return comp

    # -- reports and sets ----------------------------------------------------------------------------

    def _expire(self, now: float | None) -> None:
        if now is None:
            return
        while self.pending:
            key, s = next(iter(self.pending.items()))
            if s.last is None or now - s.last <= CONFIRM_WINDOW:
                break
            del self.pending[key]

    def _append(self, e: _Entry) -> bool:
        if len(self.timeline) >= MAX_TIMELINE:
            self.given_up[f"timeline entries beyond the first {MAX_TIMELINE:,} were not kept"] += 1
            return False
        self.timeline.append(e)
        return True

    def _report_frame(self, f: Frame, name: str, value: Value, ptype: int | None, source: str,
                      explained: bool = False) -> None:
        addr = (f.sysid, f.compid)
        self._report(addr, addr, f.record, f.time, _link(f), _verdict(f), name, value, ptype, source,
                     explained=explained)

    def _report(self, addr: Addr, sender: Addr, record: int, when: float | None, link: str, verdict: str,
                name: str, value: Value, ptype: int | None, source: str, default: Value | None = None,
                answers: bool = True, explained: bool = False, read_from: int | None = None) -> None:
        """Component `addr` holds `name` = `value` (reported in frame `record`, sent by `sender`); `answers`:
        the report can be the answer to a set (PARAM_VALUE, not a file read over FTP); `read_from`: the
        first frame of the param.pck read over FTP that reports it."""
        self._expire(when)
        s = self.pending.get((addr[0], name)) if answers else None
        if s is not None and (s.component[1] in (0, addr[1])) and s.ack is None:
            s.confirmed = same(s.value, value)
            s.confirm_frame, s.confirm_time, s.reported = record, when, value
            del self.pending[(addr[0], name)]
            explained = True  # the answer to a set: its value (the one set, or the one the vehicle kept)
        comp = self._component(addr)
        if comp is None:
            return
        comp.sources[source] = comp.sources.get(source, 0) + 1
        old = comp.params.get(name)
        if old is None:
            if len(comp.params) >= MAX_NAMES:
                self.given_up[f"{addr[0]}/{addr[1]}: parameters beyond the first {MAX_NAMES:,} not kept"] += 1
                return
            comp.params[name] = Param(value, ptype, source, record, record, default=default)
            return
        if not same(old.value, value):
            old.changes += 1
            if not explained:
                cause = (self.streams.explain(addr, name, value, record, read_from)
                         or self.missions.explain(addr, name, value, record))
                self._append(_Entry(when, record, "change", source, sender, addr, name, value, old.value, ptype,
                                    link, verdict, cause_frame=None if cause is None else cause.frame,
                                    explanation=None if cause is None else cause.text))
        old.value, old.type, old.source, old.last_frame = value, ptype, source, record
        old.reports += 1
        if default is not None:
            old.default = default

    def _set(self, f: Frame, target: Addr, name: str, value: Value, ptype: int, source: str) -> None:
        self._set_entry((f.sysid, f.compid), target, f.record, f.time, _link(f), _verdict(f), name, value, ptype,
                        source)

    def _set_entry(self, sender: Addr, target: Addr, record: int, when: float | None, link: str, verdict: str,
                   name: str, value: Value, ptype: int | None, source: str) -> None:
        """`sender` asks `target` to set `name` to `value` (in frame `record`)."""
        self._expire(when)
        key = (target[0], name)
        s = self.pending.get(key)
        if s is not None and s.sender == sender and same(s.value, value):
            s.retries += 1
            s.last = when
            self.pending.move_to_end(key)
            return
        if s is not None:
            del self.pending[key]
        comp = self.components.get(target) or next(
            (c for a, c in self.components.items() if a[0] == target[0] and name in c.params), None)
        previous = comp.params[name].value if comp is not None and name in comp.params else None
        e = _Entry(when, record, "set", source, sender, target, name, value, previous, ptype, link, verdict,
                   last=when)
        if not self._append(e):
            return
        self.pending[key] = e
        if len(self.pending) > MAX_PENDING:  # the newest but this one goes: sets waiting before a flood stay
            pop_newest(self.pending, key)
            self.given_up[f"sets waiting for their answer beyond {MAX_PENDING:,} were not matched to it"] += 1

    def _ext_ack(self, f: Frame, fields: dict[str, object]) -> None:
        name = _name(fields)
        ptype = int_field(fields, "param_type")
        result = int_field(fields, "param_result")
        raw = field_bytes(f, "param_value")
        value = from_ext_field(raw, ptype) if raw is not None else None
        s = self.pending.get((f.sysid, name))
        answered = False
        if s is not None and s.source == "PARAM_EXT_SET":
            s.ack = ACK_NAMES.get(result, str(result))
            if result == PARAM_ACK_IN_PROGRESS:
                s.ack = None  # the final answer is still to come
                s.last = f.time
                self.pending.move_to_end((f.sysid, name))
                return
            s.confirmed = result == PARAM_ACK_ACCEPTED
            s.confirm_frame, s.confirm_time, s.reported = f.record, f.time, value
            del self.pending[(f.sysid, name)]
            answered = True
        if result == PARAM_ACK_ACCEPTED and value is not None:
            self._report_frame(f, name, value, ptype, "PARAM_EXT_ACK", explained=answered)

    def _pck(self, rec: ObjectRecord) -> None:
        """A param.pck read over FTP (the server's values) or written (a client setting parameters)."""
        upload = rec.kind == FTP_WRITE
        if rec.kind not in (FTP_READ, FTP_WRITE) or not pck.is_param_pck(rec.path):
            return
        entry: dict[str, object] = {
            "path": rec.path, "direction": rec.direction, "server": _list(rec.receiver if upload else rec.sender),
            "client": _list(rec.sender if upload else rec.receiver), "first_frame": rec.first_frame,
            "last_frame": rec.last_frame, "time": rec.end, "size": rec.size, "sha256": rec.sha256,
            "complete": rec.complete}
        self.ftp.append(entry)
        server = rec.receiver if upload else rec.sender
        client = rec.sender if upload else rec.receiver
        if not rec.complete or server is None or client is None:
            entry.update({"decoded": 0, "problems": ["not decoded: the capture does not hold the whole file"]})
            return
        decoded = pck.decode(rec.data)
        entry.update({"magic": None if decoded.magic is None else f"0x{decoded.magic:04x}",
                      "num_params": decoded.num_params, "total_params": decoded.total_params,
                      "with_defaults": decoded.with_defaults, "decoded": len(decoded.params),
                      "problems": list(decoded.problems)})
        link = self.ftp_links.get(server, "-") if not upload else self.ftp_links.get(client, "-")
        verdicts = {k for per in rec.signatures.values() for k in per}
        verdict = verdicts.pop() if len(verdicts) == 1 else "mixed"
        values: dict[str, object] = {}
        entry["values"] = values
        for p in decoded.params:
            value: Value = float(p.value) if p.ap_type == 4 else int(p.value)
            values[p.name] = json_value(value)
            if upload:
                self._set_entry(client, server, rec.last_frame, rec.end, link, verdict, p.name, value, p.mav_type,
                                f"FTP upload {rec.path}")
            else:
                self._report(server, server, rec.last_frame, rec.end, link, verdict, p.name, value, p.mav_type,
                             f"FTP {rec.path}", p.default, answers=False, read_from=rec.first_frame)
        comp = self.components.get(server)
        if comp is not None and decoded.total_params is not None and not upload:
            comp.announced = decoded.total_params

    # -- the end -------------------------------------------------------------------------------------

    def finish(self) -> ParamLog:
        self.objects.finish()
        for rec in self.objects.take():
            self._pck(rec)
        comps = sorted(self.components.values(), key=lambda c: c.addr)
        for c in comps:
            if c.encoding is None and c.addr[0] in self.encodings and "PARAM_VALUE" in c.sources:
                c.encoding, c.encoding_basis = self.encodings[c.addr[0]]
        main = choose_main(comps)
        timeline = sorted((e.freeze() for e in self.timeline), key=lambda e: e.frame)
        if self.streams.unfollowed:
            self.given_up["REQUEST_DATA_STREAM requests of (system, stream) pairs beyond the first "
                          f"{MAX_KEYS:,}, not used to explain rate changes"] = self.streams.unfollowed
        log = ParamLog([c for c in comps if c.params], timeline, main, self.ftp, [], dict(self.given_up))
        log.findings = param_findings(log)
        return log


def analyse(frames: Iterable[Frame], limits: Limits | None = None) -> ParamLog:
    """The parameter timeline and final values of `frames` (in capture order)."""
    tracker = ParamTracker(limits)
    for f in frames:
        tracker.feed(f)
    return tracker.finish()


def choose_main(comps: Iterable[Component]) -> Addr | None:
    """The component whose parameters are "the" parameters: the autopilot (component 1) of the lowest
    system id holding parameters, else the component with the most."""
    with_params = [c for c in comps if c.params]
    autopilots = [c for c in with_params if c.addr[1] == 1]
    if autopilots:
        return min(autopilots, key=lambda c: c.addr).addr
    best = max(with_params, key=lambda c: (len(c.params), -c.addr[0]), default=None)
    return None if best is None else best.addr
