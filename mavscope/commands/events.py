"""`mavscope events FILE`: the flight's story in one chronological list, and the expert findings."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, cast

from mavscope.analysis.events import FIRST_KEPT, KINDS, LAST_KEPT, EventLog
from mavscope.analysis.expert import Expert
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass, print_findings
from mavscope.commands.common import console, write_json
from mavscope.notes import sort_findings
from mavscope.output.grid import columns, print_table
from mavscope.output.tables import iso

if TYPE_CHECKING:
    from mavscope.output.grid import Cell

KIND_STYLE = {"arming": "bold yellow", "mode": "cyan", "failsafe": "bold red", "reboot": "magenta",
              "link": "red", "signing": "magenta", "command": "green", "statustext": "", "mission": "blue",
              "param": "", "file": "", "vehicle": "bold"}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("events",
                       description="Every event of a capture in one chronological list: arming and disarming, mode "
                                   "changes (decoded per autopilot), mission progress, STATUSTEXT, failsafes, "
                                   "commands with their ACK, parameter changes, file transfers, signing, link loss "
                                   "and recovery; and the expert findings (docs/analysis.md).")
    add_analysis_options(p)
    p.add_argument("--kind", action="append", default=[], metavar="KIND", choices=KINDS,
                   help=f"only events of this kind (repeatable): {', '.join(KINDS)}")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    with analysis_pass(args, env) as frames:
        dialect, path, select = frames.session.dialect, frames.session.name, frames.selection
        log = EventLog(dialect)
        expert = Expert(dialect)
        for frame in frames:
            log.add(frame)
            expert.add(frame)
    result = log.finish()
    kinds = set(args.kind)
    if kinds:
        result.events = [e for e in result.events if e.kind in kinds]
    # with what the story's bounds gave up (capacity: the events left out, transfers not followed)
    findings = [f for f in sort_findings([*expert.findings(), *result.capacity]) if select.any_record(f.frames)]
    doc = result.to_json(select if select.active else None)
    if args.json:
        write_json(env, {"file": path, "filter": args.display_filter, **doc,
                         "findings": [f.to_json() for f in findings]})
        return ExitStatus.OK
    from mavscope.output.console import text

    con = console(env)
    shown = cast("list[dict]", doc["events"])

    def row(e: dict) -> list[Cell]:  # the capture's words, escaped
        sender = e["from"]
        return [str(e["frame"]), iso(e["time"]), text(e["kind"], style=KIND_STYLE.get(e["kind"], "")),
                f"{sender[0]}/{sender[1]}", text(e["text"])]

    if shown:
        print_table(con, columns("frame", "time", "kind", "from", "event", right=("frame",)), shown, row,
                    title=f"Events ({path})")
    else:
        con.print(text(f"No event in {path}" + (" matches the display filter." if select.active else ".")))
    counts = ", ".join(f"{k} {n}" for k, n in doc["counts"].items())  # type: ignore[attr-defined]
    con.print(f"{len(shown)} events listed; in the capture: {counts or 'none'}")
    for kind, n in doc["dropped"].items():  # type: ignore[attr-defined]
        con.print(f"{n} more {kind} events not listed (of each kind and sender the first {FIRST_KEPT:,} and the "
                  f"last {LAST_KEPT:,} are, and a bound in all: the capacity finding says which)")
    print_findings(con, findings)
    return ExitStatus.OK

