"""`mavscope commands FILE`: every COMMAND_LONG / COMMAND_INT with its COMMAND_ACK."""

from __future__ import annotations

import argparse
from typing import cast

from mavscope.analysis.command_log import command_json, reconstruct
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass
from mavscope.commands.common import console, write_json
from mavscope.mavlink.semantics import param_shown
from mavscope.notes import finding_line
from mavscope.output.grid import columns, many, print_lines, print_table
from mavscope.output.tables import fmt, iso, param_text

UNLABELLED = {"x": "param5", "y": "param6", "z": "param7"}  # COMMAND_INT's fields for params 5..7, by number


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("commands",
                       description="Every COMMAND_LONG and COMMAND_INT with the COMMAND_ACK that answered it.")
    add_analysis_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    with analysis_pass(args, env) as frames:
        dialect, path, select = frames.session.dialect, frames.session.name, frames.selection
        commands, orphans, given_up = reconstruct(frames, dialect)
    commands = [c for c in commands if select.any_record(c.frames)]  # a row is its command (and retries)
    orphans = [o for o in orphans if select.any_record((int(o["frame"]),))]  # type: ignore[call-overload]
    docs = [command_json(c, dialect) for c in commands]
    unanswered = sum(1 for d in docs if not d["answered"])
    capacity = given_up.finding()  # commands the matcher stopped waiting for (docs/security.md, "Bounds")
    if args.json:
        write_json(env, {"file": path, "commands": docs, "unanswered": unanswered, "unmatched_acks": orphans,
                         "given_up": given_up.count, "findings": [capacity.to_json()] if capacity else []})
        return ExitStatus.OK
    con = console(env)

    def row(d: dict[str, object]) -> list[str]:  # the fields command_json writes, with their types
        labels = cast("dict[str, str]", d["param_labels"])
        values = cast("dict[str, object]", d["params"])
        sender, target = cast("list[int]", d["from"]), cast("list[int]", d["to"])
        names = cast("dict[str, str]", d["param_names"])
        # COMMAND_INT's x/y: int32 on the wire, here in degrees or metres (not float32s)
        wire_int = ("x", "y") if d["message"] == "COMMAND_INT" else ()
        # a parameter the dialect labels is shown, with its label; one it leaves unlabelled only when it holds
        # something (semantics.param_shown, as the summary lines), as paramN (COMMAND_INT's x, y, z: param5..7)
        params = ", ".join(f"{labels.get(k) or UNLABELLED.get(k, k)} {names.get(k) or param_text(v, k not in wire_int)}"
                           for k, v in values.items() if k != "confirmation" and param_shown(labels.get(k), v))
        return [str(cast("list[int]", d["frames"])[0]), iso(cast("float | None", d["time"])),
                "{}/{}".format(*sender), "{}/{}".format(*target),
                str(d["command"]).removeprefix("MAV_CMD_"), params,
                str(d["result"]).removeprefix("MAV_RESULT_") if d["answered"] else
                "GIVEN UP" if d["given_up"] else "UNANSWERED",
                fmt(d["latency_ms"], 1), str(d["retries"])]

    if docs:
        print_table(con, columns("frame", "time", "from", "to", "command", "parameters", "result", "latency ms",
                                 "retries", right=("frame", "latency ms", "retries")),
                    docs, row, title=f"Commands ({path})")
    else:
        con.print(f"No command in {path} matches the display filter." if select.active
                  else f"No COMMAND_LONG or COMMAND_INT in {path}.")
    con.print(f"{len(docs)} commands, {unanswered} unanswered, {len(orphans)} ACKs matching no command")
    if capacity is not None:  # (its words name messages of the dialect: shown as every line here is)
        print_lines(con, (finding_line(capacity),), plain=many(1))
    print_lines(con, (f"  frame {o['frame']}: ACK {o['command']} {o['result']} from {o['from'][0]}/{o['from'][1]}"  # type: ignore[index]
                      for o in orphans), plain=many(len(orphans)))
    return ExitStatus.OK
