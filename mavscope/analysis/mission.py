"""Mission transfer reconstruction: every MISSION_COUNT / MISSION_REQUEST(_INT) / MISSION_ITEM(_INT) /
MISSION_ACK exchange of a capture rebuilt into a transfer with its items, in both directions.

A transfer is opened by a MISSION_COUNT from the system that holds the plan (the GCS in an upload,
the vehicle in a download, which a MISSION_REQUEST_LIST starts) to the system that receives it, per
mission type. Requests and items fill it; items sent more than once are kept once (the last copy) and
counted as resent; a MISSION_ACK closes it. It is `complete` when the receiver accepted it and every
item is in the capture; otherwise `reason` says why not: a NACK (the ACK's result), items missing,
cancelled by the sender, or abandoned (a new MISSION_COUNT on the same link, or the capture ends,
before any ACK).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import cast

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.mavlink.semantics import enum_name, finite, int_coordinate, is_global

MISSION_MESSAGES = frozenset({"MISSION_COUNT", "MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ITEM",
                              "MISSION_ITEM_INT", "MISSION_ACK", "MISSION_REQUEST_LIST"})
MAV_MISSION_ACCEPTED = 0
# *_INT frame variants -> the frame QGroundControl writes in a .plan
PLAN_FRAME = {5: 0, 6: 3, 11: 10}
ALTITUDE_MODE = {0: 2, 5: 2, 3: 1, 6: 1, 10: 3, 11: 3}  # QGC AltitudeMode: 1 relative, 2 AMSL, 3 terrain


@dataclass
class Item:
    seq: int
    command: int
    frame: int
    params: tuple[float, float, float, float]
    x: float  # degrees for global frames, metres otherwise
    y: float
    z: float
    current: int
    autocontinue: int
    message: str
    frames: list[int] = field(default_factory=list)

    def plan_params(self) -> list[object]:
        return [finite(p) for p in self.params] + [finite(self.x), finite(self.y), finite(self.z)]


@dataclass
class Transfer:
    sender: tuple[int, int]
    receiver: tuple[int, int]
    mission_type: int
    count: int
    direction: str  # "upload" (to the vehicle) or "download" (a MISSION_REQUEST_LIST asked for it)
    start: float | None
    frames: list[int] = field(default_factory=list)
    items: dict[int, Item] = field(default_factory=dict)
    requests: list[int] = field(default_factory=list)
    resent: dict[int, int] = field(default_factory=dict)  # seq -> extra copies
    count_resent: int = 0
    result: int | None = None
    closed: str = ""  # "ack", "cancelled", "abandoned", "end"
    end: float | None = None
    complete: bool = False
    reason: str = ""

    @property
    def missing(self) -> list[int]:
        return [s for s in range(self.count) if s not in self.items]

    def finish(self, how: str, dialect: Dialect, result: int | None = None, when: float | None = None) -> None:
        self.closed, self.result = how, result
        if when is not None:
            self.end = when
        missing = self.missing
        miss = f"items missing from the capture: {', '.join(map(str, missing))}" if missing else ""
        if how == "ack" and result == MAV_MISSION_ACCEPTED:
            self.complete = not missing
            self.reason = "accepted" if not missing else f"accepted, but {miss}"
        elif how == "ack":
            self.reason = f"NACK {_enum_name(dialect, 'MAV_MISSION_RESULT', result)}"
        elif how == "cancelled":
            self.reason = f"cancelled by the sender ({_enum_name(dialect, 'MAV_MISSION_RESULT', result)})"
        else:
            got = f"{len(self.items)} of {self.count} items"
            why = "a new MISSION_COUNT restarted it" if how == "abandoned" else "the capture ends"
            self.reason = f"abandoned: no MISSION_ACK ({why}); {got}" + (f"; {miss}" if missing else "")


def _enum_name(dialect: Dialect, enum: str, value: int | None) -> str:
    return "none" if value is None else enum_name(dialect, enum, value)


def _item(name: str, fields: dict[str, object], record: int) -> Item:
    num = cast("dict[str, float]", fields)  # every MISSION_ITEM(_INT) field is a number (int or float)
    frame = int(num.get("frame", 0))
    x, y = num.get("x", 0), num.get("y", 0)
    if name == "MISSION_ITEM_INT":
        x, y = int_coordinate(int(x), frame), int_coordinate(int(y), frame)
    return Item(int(num["seq"]), int(num["command"]), frame,
                tuple(float(num[f"param{i}"]) for i in range(1, 5)),  # type: ignore[arg-type]  # 4 params
                float(x), float(y), float(num.get("z", 0.0)),
                int(num.get("current", 0)), int(num.get("autocontinue", 1)), name, [record])


def _matches(addr: tuple[int, int], sysid: object, compid: object) -> bool:
    """Whether a message targeted at (sysid, compid) reaches `addr` (0 is a broadcast)."""
    return (sysid in (0, addr[0])) and (compid in (0, addr[1], None))


def reconstruct(frames: Iterable[Frame], dialect: Dialect) -> list[Transfer]:
    """Every mission transfer of the capture, in the order they started."""
    transfers: list[Transfer] = []
    open_: dict[tuple[tuple[int, int], int], Transfer] = {}  # (sender, mission_type) -> open transfer
    asked: dict[tuple[int, int], tuple[int, int]] = {}  # (holder sysid, type) -> asker (sysid, compid)
    for f in frames:
        md = f.msgdef
        if md is None or md.name not in MISSION_MESSAGES or f.crc_status is CrcStatus.BAD:
            continue
        fields = decode_payload(f)
        if fields is None:
            continue
        name = md.name
        me = (f.sysid, f.compid)
        mtype = int(fields.get("mission_type", 0) or 0)  # type: ignore[call-overload]
        ts, tc = fields.get("target_system"), fields.get("target_component")
        if name == "MISSION_REQUEST_LIST":
            asked[((int(ts), mtype))] = me  # type: ignore[call-overload]
            continue
        if name == "MISSION_COUNT":
            prev = open_.get((me, mtype))
            count = int(fields["count"])  # type: ignore[call-overload]
            if prev is not None and not prev.items and prev.count == count and _matches(prev.receiver, ts, tc):
                prev.count_resent += 1  # the same COUNT again: the receiver did not answer yet
                prev.frames.append(f.record)
                continue
            if prev is not None:
                prev.finish("abandoned", dialect)
            asker = asked.pop((f.sysid, mtype), None)
            direction = "download" if asker is not None and asker[0] == ts else "upload"
            receiver = (int(ts), int(tc))  # type: ignore[call-overload]
            if asker is not None and asker[0] == ts:
                receiver = asker
            new = Transfer(me, receiver, mtype, count, direction, f.time, [f.record])
            transfers.append(new)
            open_[(me, mtype)] = new
            continue
        if name in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            t = _find(open_, ts, tc, mtype, requester=me)
            if t is not None:
                t.requests.append(int(fields["seq"]))  # type: ignore[call-overload]
                t.frames.append(f.record)
                t.end = f.time
            continue
        if name in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            t = open_.get((me, mtype))
            if t is None or not _matches(t.receiver, ts, tc):
                continue
            item = _item(name, fields, f.record)
            t.frames.append(f.record)
            t.end = f.time
            old = t.items.get(item.seq)
            if old is not None:
                t.resent[item.seq] = t.resent.get(item.seq, 0) + 1
                item.frames = old.frames + item.frames
            t.items[item.seq] = item
            continue
        if name == "MISSION_ACK":
            result = int(fields.get("type", 0))  # type: ignore[call-overload]
            t = _find(open_, ts, tc, mtype, requester=me)
            if t is not None:  # from the receiver: the transfer's result
                t.frames.append(f.record)
                t.finish("ack", dialect, result, f.time)
                del open_[(t.sender, t.mission_type)]
                continue
            t = open_.get((me, mtype))
            if t is not None and _matches(t.receiver, ts, tc):  # from the sender: it gave up
                t.frames.append(f.record)
                t.finish("cancelled", dialect, result, f.time)
                del open_[(me, mtype)]
    for t in open_.values():
        t.finish("end", dialect)
    return transfers


def _find(open_: dict[tuple[tuple[int, int], int], Transfer], ts: object, tc: object, mtype: int,
          requester: tuple[int, int]) -> Transfer | None:
    """The open transfer of type `mtype` whose sender is the target (ts, tc) and receiver `requester`."""
    for (sender, t_type), t in open_.items():
        if t_type == mtype and _matches(sender, ts, tc) and t.receiver[0] == requester[0]:
            return t
    return None


def item_json(item: Item, dialect: Dialect) -> dict[str, object]:
    labels = {i: label for i, label, _ in dialect.command_params(item.command)}
    return {
        "seq": item.seq,
        "command": _enum_name(dialect, "MAV_CMD", item.command),
        "command_id": item.command,
        "frame": _enum_name(dialect, "MAV_FRAME", item.frame),
        "frame_id": item.frame,
        "params": [finite(p) for p in item.params],
        "param_labels": [labels.get(i) for i in range(1, 8)],
        "x": item.x, "y": item.y, "z": finite(item.z),
        "units": "deg" if is_global(item.frame) else "m",
        "current": item.current, "autocontinue": item.autocontinue,
        "message": item.message, "frames": item.frames,
    }


def transfer_json(t: Transfer, dialect: Dialect) -> dict[str, object]:
    return {
        "from": list(t.sender), "to": list(t.receiver), "direction": t.direction,
        "mission_type": _enum_name(dialect, "MAV_MISSION_TYPE", t.mission_type),
        "count": t.count, "complete": t.complete, "reason": t.reason,
        "result": None if t.result is None else _enum_name(dialect, "MAV_MISSION_RESULT", t.result),
        "start": t.start, "end": t.end,
        "missing": t.missing, "resent_items": sorted(t.resent), "count_resent": t.count_resent,
        "requests": len(t.requests),
        "items": [item_json(t.items[s], dialect) for s in sorted(t.items)],
        "frames": t.frames,
    }


def to_plan(transfers: list[Transfer], home: tuple[float, float, float] | None = None) -> dict[str, object]:
    """A QGroundControl .plan (JSON, version 1): the last complete (else the last) mission transfer's
    items as SimpleItems, rally points from a rally transfer, fence circles and polygons from a fence one."""

    def pick(mtype: int) -> Transfer | None:
        cands = [t for t in transfers if t.mission_type == mtype and t.items]
        done = [t for t in cands if t.complete]
        return (done or cands)[-1] if cands else None

    mission = pick(0)
    items = []
    if mission is not None:
        for seq in sorted(mission.items):
            it = mission.items[seq]
            items.append({
                "AMSLAltAboveTerrain": None, "Altitude": finite(it.z),
                "AltitudeMode": ALTITUDE_MODE.get(it.frame, 1), "autoContinue": bool(it.autocontinue),
                "command": it.command, "doJumpId": seq + 1, "frame": PLAN_FRAME.get(it.frame, it.frame),
                "params": it.plan_params(), "type": "SimpleItem",
            })
    if home is None and mission is not None and mission.items:
        first = mission.items[min(mission.items)]
        home = (first.x, first.y, 0.0)
    rally = pick(2)
    fence = pick(1)
    circles, polygons = [], []
    if fence is not None:
        poly: list[list[float]] = []
        for seq in sorted(fence.items):
            it = fence.items[seq]
            if it.command in (5001, 5002):  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION / _EXCLUSION
                poly.append([it.x, it.y])
                if len(poly) >= int(it.params[0] or 0):
                    polygons.append({"inclusion": it.command == 5001, "polygon": poly, "version": 1})
                    poly = []
            elif it.command in (5003, 5004):  # MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION / _EXCLUSION
                circles.append({"circle": {"center": [it.x, it.y], "radius": it.params[0]},
                                "inclusion": it.command == 5003, "version": 1})
    return {
        "fileType": "Plan",
        "geoFence": {"circles": circles, "polygons": polygons, "version": 2},
        "groundStation": "QGroundControl",
        "mission": {
            "cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1, "hoverSpeed": 5,
            "items": items, "plannedHomePosition": list(home) if home else [0, 0, 0], "vehicleType": 2,
            "version": 2,
        },
        "rallyPoints": {"points": [[it.x, it.y, it.z] for _, it in sorted(rally.items.items())] if rally else [],
                        "version": 2},
        "version": 1,
    }
