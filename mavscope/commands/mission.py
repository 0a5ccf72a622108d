"""`mavscope mission FILE`: every mission, fence and rally transfer rebuilt into a waypoint table, the other
mission operations (clear, set current) as events; `--plan` exports a QGroundControl .plan."""

from __future__ import annotations

import argparse
import json

from mavscope.analysis.mission import analyse, log_json, to_plan
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass
from mavscope.commands.common import OutputKind, add_output_option, check_outputs, console, write_json, write_output
from mavscope.errors import UsageError
from mavscope.notes import finding_line
from mavscope.output.grid import columns, many, print_lines, print_table
from mavscope.output.tables import coord_text, iso, listed, param_text

STATE = {"complete": "complete", "unacknowledged": "unacknowledged"}  # every other outcome: INCOMPLETE


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mission",
                       description="Rebuild every mission transfer (MISSION_COUNT, MISSION_REQUEST(_INT), "
                                   "MISSION_ITEM(_INT), MISSION_ACK) in both directions, for missions, geofences "
                                   "and rally points, and the MISSION_CLEAR_ALL / MISSION_SET_CURRENT operations.")
    add_analysis_options(p)
    add_output_option(p, "--plan", metavar="OUT.plan", kind=OutputKind.TEXT,
                      help="write what the vehicle holds at the end of the capture (its last accepted upload, clear "
                           "or download of each of mission, fence and rally) as a QGroundControl plan")
    p.add_argument("--plan-transfer", metavar="N", type=int,
                   help="with --plan: export transfer N (as numbered in the output) for its mission type instead, "
                        "e.g. a mission the vehicle no longer holds")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    report = check_outputs(args, env, stdout_used="--json" if args.json else None)  # stderr's for --plan -
    with analysis_pass(args, env) as frames:
        dialect, path, select = frames.session.dialect, frames.session.name, frames.selection
        log = analyse(frames, dialect)
    if select.active:  # every frame analysed; the transfers and operations with a matched frame reported
        log.transfers = [t for t in log.transfers if select.any_record(t.frames)]
        log.events = [e for e in log.events if select.any_record(e.frames)]
    doc = log_json(log, dialect)
    export = None
    chosen = args.plan_transfer
    if chosen is not None and not args.plan:
        raise UsageError("mission: --plan-transfer needs --plan OUT.plan")
    if chosen is not None and not 1 <= chosen <= len(log.transfers):
        raise UsageError(f"mission: --plan-transfer {chosen}: {path} has transfers 1 to {len(log.transfers)}"
                         if log.transfers else f"mission: --plan-transfer {chosen}: {path} has no transfer")
    if args.plan:
        export = to_plan(log, dialect, None if chosen is None else chosen - 1)
        if export is None:
            raise UsageError(f"mission: --plan: {path} holds no mission, fence or rally items to export")
        write_output(env, args, "--plan", args.plan, json.dumps(export.plan, indent=4) + "\n")
        for warning in export.warnings:
            env.say(f"mission: --plan: warning: {warning}")
        doc["plan"] = {"file": args.plan, **export.json()}
    if args.json:
        write_json(env, {"file": path, **doc})
        return ExitStatus.OK
    con = console(report)
    transfers: list[dict] = doc["transfers"]  # type: ignore[assignment]
    events: list[dict] = doc["events"]  # type: ignore[assignment]
    if not transfers and not events:
        con.print(f"No mission transfer in {path}.")
    plain = many(len(transfers) + len(events) + sum(len(d["items"]) for d in transfers))
    for n, d in enumerate(transfers, 1):
        state = STATE.get(d["outcome"], "INCOMPLETE")
        extra = ""
        if d["resent_items"]:
            extra += f"; resent items {d['resent_items']}"
        if d["duplicate_frames"]:
            extra += f"; {len(d['duplicate_frames'])} duplicate frame(s) ignored"
        if d["frames"]:
            extra += f"; frames {d['frames'][0]}-{d['frames'][-1]}"
        sent = "" if d["addressed_to"] == d["to"] else f" (addressed to {d['addressed_to'][0]}/{d['addressed_to'][1]})"
        span = f"items {d['partial'][0]}..{d['partial'][1]} (partial)" if d["partial"] else f"{d['count']} items"
        print_lines(con, [f"Transfer {n}: {d['direction']} {d['mission_type']} from {d['from'][0]}/{d['from'][1]} "
                          f"to {d['to'][0]}/{d['to'][1]}{sent}, {span}, {state}: {d['reason']}; "
                          f"started {iso(d['start'])}{extra}"], plain=plain)
        if not d["items"]:
            continue
        print_table(con, columns("seq", "command", "frame", "parameters", "x / lat", "y / lon", "z", "frames",
                                 right=("seq", "z")), d["items"], _item_row, plain=plain)
    print_lines(con, (f"Event {n}: {e['text']}; at {iso(e['time'])}; frames {', '.join(map(str, e['frames']))}"
                      for n, e in enumerate(events, 1)), plain=plain)
    if log.given_up is not None:  # what the tracker's bounds gave up (capacity), as audit prints it
        print_lines(con, [finding_line(log.given_up)], plain=plain)
    if args.plan and export is not None:
        for what, c in export.cleared.items():
            by = f"transfer {c['transfer']}" if c["transfer"] is not None else f"event {c['event']}"
            held = f"; before: transfer {', '.join(map(str, c['history']))}" if c["history"] else ""
            print_lines(con, [f"Plan: the vehicle holds no {what} since {iso(c['at'])} (frame {c['frame']}, {by})"
                              f"{held}"], plain=plain)
        con.print(f"Plan written to {args.plan}")
    return ExitStatus.OK


def _item_row(it: dict) -> list[str]:
    labels = it["param_labels"]
    params = ", ".join(f"{labels[i] or f'param{i + 1}'} {param_text(v)}" for i, v in enumerate(it["params"])
                       if labels[i] or (v not in (0, 0.0, None)))
    unit = {"deg": "°", "m": " m"}.get(it["units"], "")
    float32 = it["message"] != "MISSION_ITEM_INT"  # (x and y of MISSION_ITEM_INT are integers on the wire)
    return [str(it["seq"]), it["command"].removeprefix("MAV_CMD_"), it["frame"].removeprefix("MAV_FRAME_"), params,
            coord_text(it["x"], unit, float32), coord_text(it["y"], unit, float32), param_text(it["z"]),
            listed(it["frames"])]
