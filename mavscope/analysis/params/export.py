"""The JSON of the parameter analysis (`mavscope params --json`), its findings, and `--diff`."""

from __future__ import annotations

from collections.abc import Mapping

from mavscope.analysis.params.model import Addr, Component, ParamChange, ParamLog
from mavscope.analysis.params.security import category, disables
from mavscope.analysis.params.values import TYPE_NAMES, Value, json_value, same, value_text
from mavscope.analysis.selection import Selection
from mavscope.notes import Finding, finding, sort_findings

MAX_FINDINGS = 200  # security findings listed one by one; the rest are summed up in one


def _addr(a: Addr | None) -> list[int] | None:
    return None if a is None else [a[0], a[1]]


def change_json(e: ParamChange) -> dict[str, object]:
    return {"time": e.time, "frame": e.frame, "kind": e.kind, "source": e.source, "from": _addr(e.sender),
            "component": _addr(e.component), "name": e.name, "value": json_value(e.value),
            "previous": json_value(e.previous), "type": TYPE_NAMES.get(e.type or 0), "type_id": e.type,
            "link": e.link, "signature": e.signature, "confirmed": e.confirmed, "confirm_frame": e.confirm_frame,
            "confirm_time": e.confirm_time, "reported": json_value(e.reported), "retries": e.retries, "ack": e.ack,
            "security": e.security, "disables": e.disables, "explanation": e.explanation,
            "cause_frame": e.cause_frame}


def component_json(c: Component) -> dict[str, object]:
    return {"sysid": c.addr[0], "compid": c.addr[1], "count": len(c.params), "announced_count": c.announced,
            "encoding": c.encoding, "encoding_basis": c.encoding_basis or None, "sources": dict(c.sources),
            "parameters": {n: {"value": json_value(p.value), "type": TYPE_NAMES.get(p.type or 0), "type_id": p.type,
                               "source": p.source, "first_frame": p.first_frame, "last_frame": p.last_frame,
                               "reports": p.reports, "changes": p.changes,
                               **({"default": json_value(p.default)} if p.default is not None else {})}
                           for n, p in sorted(c.params.items())}}


def describe(e: ParamChange) -> str:
    who = f"{e.sender[0]}/{e.sender[1]}"
    was = f" (was {value_text(e.previous)})" if e.previous is not None else ""
    if e.kind == "set":
        answer = {True: f"; confirmed by the vehicle (frame {e.confirm_frame})",
                  False: f"; the vehicle reported {value_text(e.reported)} instead (frame {e.confirm_frame})",
                  None: "; not confirmed in the capture"}[e.confirmed]
        text = f"{e.name} set to {value_text(e.value)}{was} by {who} with {e.source} over {e.link}, {e.signature}"
        return text + answer
    why = e.explanation or "with no set in the capture to explain it"
    return (f"{e.name} changed to {value_text(e.value)}{was} on {e.component[0]}/{e.component[1]}, reported by "
            f"{e.source} over {e.link}, {e.signature}, {why}")


def param_findings(log: ParamLog) -> list[Finding]:
    out: list[Finding] = []
    flagged = [e for e in log.timeline if e.security is not None]
    for e in flagged[:MAX_FINDINGS]:
        frames = [e.frame] + ([e.confirm_frame] if e.confirm_frame is not None else [])
        code = "param-protection-disabled" if e.disables else "param-security-change"
        extra = f": turns off {e.disables}" if e.disables else ""
        out.append(finding(code, f"{e.security} parameter {describe(e)}{extra}", frames))
    if len(flagged) > MAX_FINDINGS:
        rest = flagged[MAX_FINDINGS:]
        out.append(finding("param-security-change", f"{len(rest)} more security-relevant parameter events "
                                                    f"({', '.join(sorted({e.name for e in rest})[:20])}...)",
                           [e.frame for e in rest[:50]]))
    return sort_findings(out)


def params_json(log: ParamLog, selection: Selection | None = None) -> dict[str, object]:
    sel = selection or Selection()
    timeline = [e for e in log.timeline
                if sel.any_record([e.frame] + ([e.confirm_frame] if e.confirm_frame is not None else []))]
    return {
        "main_component": _addr(log.main),
        "final": {n: json_value(v) for n, v in log.final.items()},
        "components": [component_json(c) for c in log.components],
        "timeline": [change_json(e) for e in timeline],
        "sets": sum(1 for e in timeline if e.kind == "set"),
        "confirmed": sum(1 for e in timeline if e.kind == "set" and e.confirmed),
        "unexplained": sum(1 for e in timeline if e.kind == "change" and e.explanation is None),
        "ftp": log.ftp,
        "findings": [f.to_json() for f in log.findings if not sel.active or sel.any_record(f.frames)],
        "limits": {"given_up": log.given_up},
    }


def diff(here: Mapping[str, Value], there: Mapping[str, Value]) -> dict[str, object]:
    """Parameters only here, only there, and with other values (floats compared as float32)."""
    changed = {n: [json_value(here[n]), json_value(there[n])] for n in sorted(here.keys() & there.keys())
               if not same(here[n], there[n])}
    names = sorted(changed) + sorted(here.keys() ^ there.keys())
    return {
        "only_here": {n: json_value(here[n]) for n in sorted(here.keys() - there.keys())},
        "only_there": {n: json_value(there[n]) for n in sorted(there.keys() - here.keys())},
        "changed": changed,
        "security": {n: c for n in names if (c := category(n)) is not None},
        "disables": {n: {"here": disables(n, here[n]) if n in here else None,
                         "there": disables(n, there[n]) if n in there else None}
                     for n in names if (n in here and disables(n, here[n])) or (n in there and disables(n, there[n]))},
    }
