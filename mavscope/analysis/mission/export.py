"""The mission log as JSON (docs/analysis.md) and as a QGroundControl .plan.

The .plan follows QGroundControl's format (docs/en/qgc-dev-guide/file_formats/plan.md and what
MissionController, GeoFenceController, QGCFencePolygon, QGCFenceCircle and RallyPointController save):
`firmwareType` and `vehicleType` are the vehicle's HEARTBEAT autopilot and type; on ArduPilot mission
item 0 is the home position, which QGroundControl shows as `plannedHomePosition` and keeps out of the
items (so `doJumpId` is the item's seq there, seq + 1 elsewhere).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mavscope.analysis.mission.choose import WHAT, Cleared, choose
from mavscope.analysis.mission.describe import event_text, result_name
from mavscope.analysis.mission.model import (
    COMPLETE,
    Ack,
    Event,
    Item,
    MissionLog,
    Transfer,
    role,
)
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.semantics import coordinate_unit, enum_name, float_text, is_global

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
# *_INT frame variants -> the frame QGroundControl writes in a .plan
PLAN_FRAME = {5: 0, 6: 3, 11: 10}
# QGroundControl's AltMode: 1 relative (GLOBAL_RELATIVE_ALT), 2 absolute (GLOBAL), 4 terrain frame
ALTITUDE_MODE = {0: 2, 5: 2, 3: 1, 6: 1, 10: 4, 11: 4}
FENCE_RETURN, POLY_IN, POLY_OUT, CIRCLE_IN, CIRCLE_OUT = 5000, 5001, 5002, 5003, 5004  # MAV_CMD_NAV_FENCE_*
RALLY_POINT = 5100  # MAV_CMD_NAV_RALLY_POINT


def _ack_json(a: Ack, dialect: Dialect) -> dict[str, object]:
    return {"from": list(a.sender), "result": result_name(dialect, a.result), "result_id": a.result,
            "frame": a.record, "time": a.time, "role": a.role}


def item_json(item: Item, dialect: Dialect) -> dict[str, object]:
    labels = {i: label for i, label, _ in dialect.command_params(item.command)}
    params, x, y, z = item.shown()  # (a float32 as its shortest decimal: 30.48)
    return {
        "seq": item.seq,
        "command": enum_name(dialect, "MAV_CMD", item.command),
        "command_id": item.command,
        "frame": enum_name(dialect, "MAV_FRAME", item.frame),
        "frame_id": item.frame,
        "params": params,
        "param_labels": [labels.get(i) for i in range(1, 8)],
        "x": x, "y": y, "z": z,
        "units": coordinate_unit(item.frame),
        "current": item.current, "autocontinue": item.autocontinue,
        "message": item.message, "frames": item.frames,
    }


def transfer_json(t: Transfer, dialect: Dialect) -> dict[str, object]:
    return {
        "from": list(t.sender), "to": list(t.receiver), "direction": t.direction,
        "direction_basis": t.direction_basis,
        "addressed_to": list(t.addressed) if t.addressed is not None else list(t.receiver),
        "partial": [t.first, t.count - 1] if t.partial else None,
        "mission_type": enum_name(dialect, "MAV_MISSION_TYPE", t.mission_type), "mission_type_id": t.mission_type,
        "count": t.count, "complete": t.complete, "outcome": t.outcome, "reason": t.reason,
        "result": result_name(dialect, t.result), "closed": t.closed,
        "start": t.start, "end": t.end,
        "missing": t.missing, "missing_count": t.missing_count,
        "resent_items": sorted(t.resent), "resent_changed": sorted(t.resent_changed),
        "count_resent": t.count_resent, "requests": len(t.requests),
        "acks": [_ack_json(a, dialect) for a in t.acks],
        "duplicate_frames": t.duplicates, "late_frames": t.late_frames, "receiver_silent": t.receiver_silent,
        "items": [item_json(t.items[s], dialect) for s in sorted(t.items)],
        "frames": t.frames,
    }


def event_json(ev: Event, dialect: Dialect) -> dict[str, object]:
    return {
        "kind": ev.kind, "from": list(ev.sender), "to": list(ev.target),
        "addressed_to": list(ev.addressed) if ev.addressed is not None else list(ev.target),
        "mission_type": enum_name(dialect, "MAV_MISSION_TYPE", ev.mission_type), "mission_type_id": ev.mission_type,
        "time": ev.time, "frames": ev.frames,
        "result": result_name(dialect, ev.ack.result) if ev.ack is not None else None,
        "ack_frame": ev.ack.record if ev.ack is not None else None,
        "repeated_ack_frames": [a.record for a in ev.repeats],
        "seq": ev.seq, "reported_seq": ev.reported, "confirmed": ev.confirmed, "reply_frame": ev.reply_frame,
        "messages": dict(ev.messages), "seqs": ev.seqs,
        "text": event_text(ev, dialect),
    }


def log_json(log: MissionLog, dialect: Dialect) -> dict[str, object]:
    return {"transfers": [transfer_json(t, dialect) for t in log.transfers],
            "events": [event_json(ev, dialect) for ev in log.events],
            "duplicates": log.duplicates,
            "findings": [log.given_up.to_json()] if log.given_up is not None else []}  # capacity: bounds' give-ups


@dataclass
class PlanExport:
    """A .plan document and where each part of it came from."""

    plan: dict[str, object]
    mission: int | None  # index into MissionLog.transfers of each exported transfer
    fence: int | None
    rally: int | None
    firmware_type: int
    vehicle_type: int
    home_source: str
    warnings: list[str] = field(default_factory=list)
    # "mission", "fence", "rally" -> the vehicle holds none since: {"how", "at", "frame", "transfer",
    # "event", "history"} (choose.py)
    cleared: dict[str, Cleared] = field(default_factory=dict)
    vehicle: list[int] | None = None  # the vehicle whose plan this is

    def json(self) -> dict[str, object]:
        def n(i: int | None) -> int | None:
            return None if i is None else i + 1  # numbered as the text output numbers transfers

        return {"mission_transfer": n(self.mission), "fence_transfer": n(self.fence), "rally_transfer": n(self.rally),
                "vehicle": self.vehicle, "cleared": self.cleared,
                "firmwareType": self.firmware_type, "vehicleType": self.vehicle_type,
                "home_source": self.home_source, "warnings": self.warnings}


def pick(transfers: list[Transfer], mtype: int) -> int | None:
    """The best transfer of `mtype` there is (the TUI's choice; the plan's is choose.py): the last complete
    one with items, else the last with every item, else the last with any item."""
    best: tuple[int, int] | None = None
    for i, t in enumerate(transfers):
        if t.mission_type == mtype and t.items:
            rank = (2 if t.complete else 1 if not t.missing else 0, i)
            best = rank if best is None or rank > best else best
    return None if best is None else best[1]


def _vehicle(log: MissionLog, t: Transfer) -> tuple[tuple[int, int], tuple[int, int] | None]:
    """The vehicle end of a transfer and its (MAV_TYPE, MAV_AUTOPILOT)."""
    ends = [t.receiver, t.sender] if t.direction == "upload" else [t.sender, t.receiver]
    for end in ends:
        hb = log.heartbeat_of(end)
        if hb is not None and role(hb) == "vehicle":
            return end, hb
    return ends[0], None


def _simple_item(it: Item, jump_id: int) -> dict[str, object]:
    doc: dict[str, object] = {}
    if is_global(it.frame) and (it.x or it.y):  # QGroundControl writes these for items with a position
        doc.update({"AMSLAltAboveTerrain": None, "Altitude": it.shown()[3], "AltitudeMode": ALTITUDE_MODE[it.frame]})
    doc.update({"autoContinue": bool(it.autocontinue), "command": it.command, "doJumpId": jump_id,
                "frame": PLAN_FRAME.get(it.frame, it.frame), "params": it.plan_params(), "type": "SimpleItem"})
    return doc


def _position(it: Item) -> list[float] | None:
    """The item's latitude and longitude, None when either is not a finite number (MISSION_ITEM's floats
    can be NaN or infinite: no point of a .plan, a GeoJSON, a KML or a GPX file); MISSION_ITEM's float32s as
    their shortest decimals (Item.shown)."""
    _, x, y, _ = it.shown()
    return [x, y] if isinstance(x, float) and isinstance(y, float) else None


def _vertex_count(p: float) -> int | None:
    """A polygon vertex's param1, the polygon's vertex count: None unless a whole number 1..65535."""
    return int(p) if math.isfinite(p) and p == int(p) and 1 <= p <= 65535 else None


def _fence(t: Transfer, warnings: list[str]) -> dict[str, object]:
    circles: list[object] = []
    polygons: list[object] = []
    doc: dict[str, object] = {"circles": circles, "polygons": polygons, "version": 2}
    poly: list[list[float] | None] = []
    want, inclusion, last = 0, True, -1

    def close() -> None:
        if len(poly) < want:
            warnings.append(f"fence polygon ending at item {last} has {len(poly)} of {want} vertices: left out")
        elif any(v is None for v in poly):
            warnings.append(f"fence polygon ending at item {last} has a vertex that is not a position: left out")
        else:
            polygons.append({"inclusion": inclusion, "polygon": list(poly), "version": 1})
        poly.clear()

    for seq in sorted(t.items):
        it = t.items[seq]
        if it.command in (POLY_IN, POLY_OUT):
            if poly and (seq != last + 1 or (it.command == POLY_IN) != inclusion):
                close()
            if not poly:
                count = _vertex_count(it.params[0])
                if count is None:
                    warnings.append(f"fence item {seq}: vertex count {float_text(it.params[0])} is not a whole number "
                                    "of 1 to 65535: left out")
                    last = seq
                    continue
                want, inclusion = count, it.command == POLY_IN
            poly.append(_position(it))
            last = seq
            if len(poly) >= want:
                close()
            continue
        if poly:  # a polygon's vertices are consecutive items
            close()
        if it.command in (CIRCLE_IN, CIRCLE_OUT, FENCE_RETURN):
            where, radius = _position(it), it.shown()[0][0]
            if where is None or (it.command != FENCE_RETURN and radius is None):
                warnings.append(f"fence item {seq}: its position or radius is not a finite number: left out")
            elif it.command == FENCE_RETURN:
                doc["breachReturn"] = [*where, it.shown()[3]]
            else:
                circles.append({"circle": {"center": where, "radius": radius},
                                "inclusion": it.command == CIRCLE_IN, "version": 1})
        else:
            warnings.append(f"fence item {seq}: command {it.command} has no place in a .plan: left out")
        last = seq
    if poly:
        close()
    return doc


def to_plan(log: MissionLog, dialect: Dialect, chosen: int | None = None) -> PlanExport | None:
    """A QGroundControl .plan (JSON, version 1) of what one vehicle holds at the end of the capture
    (choose.py; `chosen`, an index into log.transfers, exports that transfer for its type instead); None
    when no transfer has items."""
    transfers = log.transfers
    if not any(t.items for t in transfers):
        return None
    choice = choose(log, chosen)
    warnings = choice.warnings
    secs = choice.sections
    mi, fi, ri = secs[0].transfer, secs[1].transfer, secs[2].transfer
    for i, what in ((mi, "mission"), (fi, "fence"), (ri, "rally")):
        if i is not None and transfers[i].outcome != COMPLETE:
            warnings.append(f"the exported {what} (transfer {i + 1}) is incomplete: {transfers[i].reason}")
    first = next((i for i in (mi, fi, ri) if i is not None), None)
    if first is not None:
        vehicle, hb = _vehicle(log, transfers[first])
    else:
        vehicle = choice.vehicle or (0, 0)
        hb = log.heartbeat_of(vehicle)
    if hb is None:
        warnings.append(f"no HEARTBEAT from the vehicle {vehicle[0]}/{vehicle[1]}: firmwareType and vehicleType "
                        f"0 (generic)")
    vehicle_type, firmware = hb if hb is not None else (0, 0)
    ardupilot = firmware == MAV_AUTOPILOT_ARDUPILOTMEGA
    items: list[object] = []
    home: list[object] | None = None
    source = ""
    mission_items = secs[0].items
    if mission_items is not None:
        mission = mission_items
        seqs = sorted(mission.items)
        if ardupilot:  # item 0 is home
            seqs = [s for s in seqs if s != 0]
            zero = mission.items.get(0)
            if zero is not None and (zero.x or zero.y):
                home, source = list(zero.shown()[1:]), "mission item 0 (ArduPilot home)"
            elif zero is not None:
                warnings.append("mission item 0 (ArduPilot's home) is at 0, 0: home was not set yet")
            else:
                warnings.append("mission item 0 (ArduPilot's home) is not in the capture")
        items = [_simple_item(mission.items[s], s if ardupilot else s + 1) for s in seqs]
    if home is None and vehicle[0] in log.homes:
        home, source = list(log.homes[vehicle[0]]), "HOME_POSITION"
    if home is None and mission_items is not None:
        located = [it for _, it in sorted(mission_items.items.items()) if is_global(it.frame) and (it.x or it.y)]
        if located:
            home, source = [*located[0].shown()[1:3], 0.0], "first item's position"
            warnings.append("plannedHomePosition is the first item's position at altitude 0 (no HOME_POSITION)")
    if home is None:
        home, source = [0, 0, 0], "none"
        warnings.append("no home position in the capture: plannedHomePosition is 0, 0, 0")
    fence_items, rally_items = secs[1].items, secs[2].items
    fence = _fence(fence_items, warnings) if fence_items is not None else {"circles": [], "polygons": [], "version": 2}
    points: list[object] = []
    if rally_items is not None:
        for seq, it in sorted(rally_items.items.items()):
            where = _position(it)
            if it.command != RALLY_POINT:
                warnings.append(f"rally item {seq}: command {it.command} is not a rally point: left out")
            elif where is None:
                warnings.append(f"rally item {seq}: its position is not a finite number: left out")
            else:
                points.append([*where, it.shown()[3]])
    plan = {
        "fileType": "Plan",
        "geoFence": fence,
        "groundStation": "QGroundControl",
        "mission": {
            "cruiseSpeed": 15, "firmwareType": firmware, "globalPlanAltitudeMode": 1, "hoverSpeed": 5,
            "items": items, "plannedHomePosition": home, "vehicleType": vehicle_type, "version": 2,
        },
        "rallyPoints": {"points": points, "version": 2},
        "version": 1,
    }
    cleared = {WHAT[m]: sec.cleared for m, sec in secs.items() if sec.cleared is not None}
    return PlanExport(plan, mi, fi, ri, firmware, vehicle_type, source, warnings, cleared,
                      None if choice.vehicle is None else list(choice.vehicle))
