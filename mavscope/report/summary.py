"""What happened, first: the part of the report an investigator reads in a minute.

From what the analyses gave (no analysis of its own): the vehicles and ground stations their HEARTBEATs
name (mavscope.analysis.vehicles.Systems: type, autopilot, last mode) with the firmware an
AUTOPILOT_VERSION sent; who commanded what (the story's command, parameter and mission events, grouped by
sender and target); signing per link (`stats`' links: their signature verdicts).
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, Any

from mavscope.mavlink.dialect import Dialect

if TYPE_CHECKING:
    from mavscope.report.collect import Collected


class Names:
    """Enum entry names of the dialect, without their prefix (`MAV_TYPE_QUADROTOR` -> `QUADROTOR`)."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect

    def enum(self, enum: str, value: int, prefix: str = "") -> str:
        e = self.dialect.enums.get(enum)
        name = e.name_of(value) if e is not None else None
        return name.removeprefix(prefix) if name is not None else str(value)


def _vehicles(c: Collected, names: Names) -> tuple[list[dict[str, object]], list[dict[str, object]]]:
    systems = c.systems
    vehicles, stations = [], []
    for (sysid, compid), hb in sorted(systems.last.items()):
        firmware = c.firmware.get((sysid, compid)) or next(
            (v for (s, _), v in sorted(c.firmware.items()) if s == sysid), None) if systems.is_vehicle(
            (sysid, compid)) else None
        row: dict[str, object] = {
            "sysid": sysid, "compid": compid, "type": names.enum("MAV_TYPE", hb.type, "MAV_TYPE_"),
            "autopilot": names.enum("MAV_AUTOPILOT", hb.autopilot, "MAV_AUTOPILOT_"),
            "state": names.enum("MAV_STATE", hb.system_status, "MAV_STATE_")}
        if systems.is_vehicle((sysid, compid)):
            row |= {"mode": systems.mode_name(hb), "armed": hb.armed, "firmware": firmware}
            vehicles.append(row)
        elif hb.type in systems.modes.gcs:
            stations.append(row)
    return vehicles, stations


def _commanders(events: list[dict[str, Any]]) -> list[dict[str, object]]:
    """Per (sender, target, what): how many times, how many accepted or confirmed, the first frame."""
    rows: dict[tuple[tuple[int, ...], tuple[int, ...], str], list[int]] = {}
    for e in events:
        kind, d = e["kind"], e["details"]
        if not isinstance(d, dict):
            continue
        if kind == "command":
            what = str(d.get("command", "SET_MODE" if "mode" in d else "command")).removeprefix("MAV_CMD_")
            ok = d.get("result") in ("MAV_RESULT_ACCEPTED", "ACCEPTED") or d.get("what") == "set_mode"
        elif kind == "param" and d.get("what") == "set":
            what, ok = f"set {d.get('name')}", d.get("confirmed") is True
        elif kind == "mission" and d.get("what") == "transfer" and d.get("direction") == "upload":
            what, ok = f"upload {d.get('mission_type')}", d.get("complete") is True
        else:
            continue
        sender, target = tuple(e["from"]), tuple(e["to"] or ())
        r = rows.setdefault((sender, target, what), [0, 0, int(e["frame"])])
        r[0] += 1
        r[1] += int(bool(ok))
    return [{"from": list(s), "to": list(t), "what": w, "count": n, "accepted": a, "first_frame": first}
            for (s, t, w), (n, a, first) in sorted(rows.items())]


def _signing(stats: dict[str, Any]) -> list[dict[str, object]]:
    out = []
    for lk in stats["links"]:
        sig: dict[str, int] = lk["signature"]
        signed = sum(n for k, n in sig.items() if k != "unsigned")
        verdict = "unsigned" if not signed else "signed" if not sig.get("unsigned") else "mixed"
        out.append({"sysid": lk["sysid"], "compid": lk["compid"], "frames": lk["received"], "verdict": verdict,
                    "signature": dict(sorted(sig.items())), "endpoints": lk["endpoints"]})
    return out


def summary(c: Collected, stats: dict[str, Any], events: list[dict[str, Any]], names: Names,
            ) -> dict[str, object]:
    vehicles, stations = _vehicles(c, names)
    kinds = Counter(str(e["kind"]) for e in events)
    return {"vehicles": vehicles, "ground_stations": stations, "commanders": _commanders(events),
            "signing": _signing(stats), "event_counts": dict(sorted(c.story.counts.items())),
            "events_listed": dict(sorted(kinds.items()))}
