"""The report as data: one JSON document (docs/report.md, docs/report.schema.json) that the HTML page is
rendered from, so that the page and `--json` state the same facts.

`input_doc(...)` turns what the analyses gave for one capture (`collect.Collected`) into its part of the
document; `document(...)` puts the inputs together under the chain of custody. Everything is sorted (by
frame, then by key), so the same inputs give the same document but for `custody.analysed_at`.
"""

from __future__ import annotations

import bisect
import shlex
from collections.abc import Sequence
from typing import Any

import orjson

from mavscope.analysis.mission import Item
from mavscope.analysis.params import diff
from mavscope.analysis.params.values import Value
from mavscope.notes import CODES, Severity
from mavscope.output.geo import geojson
from mavscope.report.collect import PLOTS, Collected, finite
from mavscope.report.custody import FileHash
from mavscope.report.summary import Names, summary

SCHEMA = "mavscope-report"
SCHEMA_VERSION = 1
SHOW_FRAMES = 8  # frames a "show them" command names at most (the finding lists them all)


def show_command(path: str, frames: Sequence[int]) -> str | None:
    """The command that shows `frames` of the capture at `path` in full (`read -Y ... -V`), None for none."""
    if not frames:
        return None
    picked = sorted(set(frames))[:SHOW_FRAMES]
    flt = f"frame.number == {picked[0]}" if len(picked) == 1 else \
        "frame.number in {" + " ".join(map(str, picked)) + "}"
    return f"mavscope read {shlex.quote(path)} -Y {shlex.quote(flt)} -V"


def _finding(f_json: dict[str, Any], path: str) -> dict[str, object]:
    code = CODES.get(str(f_json["code"]))
    frames = f_json.get("frames") or []
    return {**f_json, "summary": code.summary if code is not None else "",
            "explanation": code.explanation if code is not None else "",
            "group": code.group.value if code is not None else "",
            "show": show_command(path, frames)}


def _series(c: Collected) -> list[dict[str, object]]:
    out = []
    for (expr, title, unit, divisor), s in zip(PLOTS, c.plotter.series):
        doc: dict[str, Any] = s.to_json()
        out.append({"field": expr, "title": title, "unit": unit, "divisor": divisor, "count": doc["count"],
                    "interval": doc["interval"], "min": doc["min"], "max": doc["max"],
                    "buckets": [[b["start"], b["min"], b["max"]] for b in doc["buckets"]]})
    return out


def _progress(events: list[dict[str, Any]]) -> list[tuple[int, int, str, int]]:
    """(frame, vehicle's system, "reached" or "current", seq) of the story's mission progress events."""
    out = []
    for e in events:
        d = e["details"]
        if e["kind"] == "mission" and isinstance(d, dict) and d.get("what") in ("reached", "current") \
                and isinstance(d.get("seq"), int):
            out.append((int(e["frame"]), int(e["from"][0]), str(d["what"]), int(d["seq"])))
    return out


def _item(it: Item, names: Names) -> dict[str, object]:
    """A mission item as `mission --json` shows its numbers (Item.shown: float32s as their shortest text)."""
    params, x, y, z = it.shown()
    return {"seq": it.seq, "command": names.enum("MAV_CMD", it.command, "MAV_CMD_"), "params": params, "x": x,
            "y": y, "z": z, "frame": it.frames[0] if it.frames else None}


def _missions(c: Collected, names: Names, events: list[dict[str, Any]]) -> dict[str, object]:
    """Every mission, fence and rally transfer (the story's mission tracker: `mission`'s) with its items; for
    each mission upload, the items its vehicle then said it reached (MISSION_ITEM_REACHED) and was on
    (MISSION_CURRENT), from its first frame to the next mission upload to that vehicle; and per vehicle
    every item reached and on."""
    progress = _progress(events)
    log = c.missions
    transfers = list(log.transfers) if log is not None else []
    uploads: dict[int, list[int]] = {}  # vehicle's system -> first frames of its mission uploads
    for t in transfers:
        if t.direction == "upload" and t.mission_type == 0 and t.frames:
            uploads.setdefault(t.receiver[0], []).append(t.frames[0])
    for starts in uploads.values():
        starts.sort()
    by_vehicle: dict[int, tuple[list[int], list[tuple[str, int]]]] = {}  # system -> (frames, (what, seq)), by frame
    for frame, sysid, what, seq in sorted(progress):
        got = by_vehicle.setdefault(sysid, ([], []))
        got[0].append(frame)
        got[1].append((what, seq))
    out = []
    for n, t in enumerate(transfers, 1):
        doc: dict[str, object] = {
            "transfer": n, "direction": t.direction,
            "mission_type": names.enum("MAV_MISSION_TYPE", t.mission_type, "MAV_MISSION_TYPE_"),
            "from": list(t.sender), "to": list(t.receiver), "count": t.count, "outcome": t.outcome,
            "reason": t.reason, "start": finite(t.start), "frames": [t.frames[0], t.frames[-1]] if t.frames else [],
            "items": [_item(it, names) for it in sorted(t.items.values(), key=lambda it: it.seq)]}
        if t.direction == "upload" and t.mission_type == 0 and t.frames:
            vehicle, first = t.receiver[0], t.frames[0]
            starts = uploads[vehicle]
            later = bisect.bisect_right(starts, first)
            frames, said = by_vehicle.get(vehicle, ([], []))
            a = bisect.bisect_left(frames, first)
            z = bisect.bisect_left(frames, starts[later]) if later < len(starts) else len(frames)
            doc["reached"] = sorted({seq for what, seq in said[a:z] if what == "reached"})
            doc["current"] = sorted({seq for what, seq in said[a:z] if what == "current"})
        out.append(doc)
    per: dict[int, dict[str, set[int]]] = {}
    for _frame, sysid, what, seq in progress:
        per.setdefault(sysid, {"reached": set(), "current": set()})[what].add(seq)
    return {"transfers": out,
            "progress": [{"sysid": s, "reached": sorted(v["reached"]), "current": sorted(v["current"])}
                         for s, v in sorted(per.items())]}


def _params(c: Collected, events: list[dict[str, Any]], other: tuple[str, dict[str, Value]] | None,
            ) -> dict[str, object]:
    changes = [{"frame": e["frame"], "time": e["time"], "from": e["from"], "to": e["to"], "text": e["text"],
                **{k: v for k, v in e["details"].items()
                   if k in ("what", "name", "value", "previous", "confirmed", "confirm_frame", "source", "signature",
                            "security", "ack", "retries")}}
               for e in events if e["kind"] == "param"]
    log = c.params
    doc: dict[str, object] = {"changes": changes,
                              "main_component": list(log.main) if log is not None and log.main else None,
                              "final_count": len(log.final) if log is not None else 0}
    if other is not None and log is not None:
        name, values = other
        d = diff(log.final, values)
        doc["diff"] = {"other": name, **{k: d[k] for k in sorted(d)}}
    return doc


def _files(events: list[dict[str, Any]]) -> list[dict[str, object]]:
    keys = ("object", "path", "name", "direction", "size", "received", "complete", "sha256", "last_frame",
            "frame_count", "runs_as_code")
    return [{"frame": e["frame"], "from": e["from"], "to": e["to"], "text": e["text"],
             **{k: e["details"].get(k) for k in keys}}
            for e in events if e["kind"] == "file" and e["details"].get("what") == "object"]


def _map(c: Collected, names: Names) -> dict[str, object]:
    """The tracks with the mission, fence and rally points as `track --geojson` writes them."""
    return geojson(c.tracks, names.dialect)


def input_doc(c: Collected, file: FileHash, kind: str, engine: str, names: Names,
              other: tuple[str, dict[str, Value]] | None = None) -> dict[str, object]:
    """One capture's part of the report (see the module docstring)."""
    stats = c.stats.to_json()
    totals: dict[str, Any] = stats["totals"]  # type: ignore[assignment]
    start, duration = totals["start"], totals["duration"]
    events_doc = c.story.to_json()
    events: list[dict[str, Any]] = events_doc["events"]  # type: ignore[assignment]
    findings = [_finding(f.to_json(), file.path) for f in c.findings]
    for e in events:
        e["show"] = show_command(file.path, [e["frame"]])
    by_severity = {s.value: sum(1 for f in c.findings if f.severity is s) for s in reversed(Severity)}
    return {
        "file": file.to_json(), "kind": kind, "engine": engine, "frames": c.frames,
        "span": {"start": finite(start), "end": finite(start + duration) if start is not None and duration is not None
                 else None, "duration": finite(duration)},
        "summary": summary(c, stats, events, names),
        "findings_by_severity": by_severity,
        "findings": findings,
        "stats": stats,
        "events": events_doc,
        "map": _map(c, names),
        "plots": _series(c),
        "signing_over_time": c.verdicts.to_json(),
        "missions": _missions(c, names, events),
        "params": _params(c, events, other),
        "files": _files(events),
    }


def json_text(doc: dict[str, object]) -> str:
    """The document as JSON text: keys sorted, NaN and the infinities as null, one line break at the end."""
    return orjson.dumps(doc, option=orjson.OPT_INDENT_2 | orjson.OPT_APPEND_NEWLINE | orjson.OPT_SORT_KEYS
                        | orjson.OPT_NON_STR_KEYS).decode("utf-8")


def document(custody: dict[str, object], inputs: list[dict[str, object]]) -> dict[str, object]:
    return {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "custody": custody, "inputs": inputs}
