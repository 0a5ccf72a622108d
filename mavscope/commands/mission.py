"""`mavscope mission FILE`: every mission transfer rebuilt into a waypoint table; `--plan` exports a
QGroundControl .plan."""

from __future__ import annotations

import argparse
import json

from mavscope.analysis.mission import reconstruct, to_plan, transfer_json
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, read_frames
from mavscope.commands.common import console, write_json
from mavscope.errors import UsageError
from mavscope.mavlink.frame import Frame, decode_payload
from mavscope.output.tables import fmt, iso


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mission", help="rebuild mission uploads and downloads; export a QGroundControl .plan",
                       description="Rebuild every mission transfer (MISSION_COUNT, MISSION_REQUEST(_INT), "
                                   "MISSION_ITEM(_INT), MISSION_ACK) in both directions.")
    add_analysis_options(p)
    p.add_argument("--plan", metavar="OUT.plan",
                   help="write the last complete mission (else the last one with items) as a QGroundControl plan")
    p.set_defaults(run=run)


def _home(frames: list[Frame]) -> tuple[float, float, float] | None:
    for f in reversed(frames):
        if f.msgdef is not None and f.msgdef.name == "HOME_POSITION":
            d = decode_payload(f)
            if d is not None:
                return (int(d["latitude"]) / 1e7, int(d["longitude"]) / 1e7,  # type: ignore[call-overload]
                        int(d["altitude"]) / 1000)  # type: ignore[call-overload]
    return None


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    frames, dialect, path = read_frames(args, env)
    transfers = reconstruct(frames, dialect)
    if args.plan:
        if not any(t.items and t.mission_type == 0 for t in transfers):
            raise UsageError(f"mission: --plan: {path} holds no mission items to export")
        plan = to_plan(transfers, _home(frames))
        try:
            with open(args.plan, "w", encoding="utf-8") as fh:
                json.dump(plan, fh, indent=4)
                fh.write("\n")
        except OSError as exc:
            raise UsageError(f"mission: --plan {args.plan}: {exc.strerror or exc}") from None
    docs = [transfer_json(t, dialect) for t in transfers]
    if args.json:
        write_json(env, {"file": path, "transfers": docs})
        return ExitStatus.OK
    from rich.table import Table

    con = console(env)
    if not docs:
        con.print(f"No mission transfer in {path}.")
    for n, d in enumerate(docs, 1):
        state = "complete" if d["complete"] else "INCOMPLETE"
        con.print(f"Transfer {n}: {d['direction']} {d['mission_type']} from {d['from'][0]}/{d['from'][1]} "  # type: ignore[index]
                  f"to {d['to'][0]}/{d['to'][1]}, {d['count']} items, {state}: {d['reason']}; "  # type: ignore[index]
                  f"started {iso(d['start'])}"  # type: ignore[arg-type]
                  + (f"; resent items {d['resent_items']}" if d["resent_items"] else "")
                  + (f"; frames {d['frames'][0]}-{d['frames'][-1]}" if d["frames"] else ""))  # type: ignore[index]
        if not d["items"]:
            continue
        t = Table(title_justify="left")
        for col in ("seq", "command", "frame", "parameters", "x / lat", "y / lon", "z", "frames"):
            t.add_column(col, justify="right" if col in ("seq", "z") else "left")
        for it in d["items"]:  # type: ignore[attr-defined]
            labels = it["param_labels"]
            params = ", ".join(f"{labels[i] or f'param{i + 1}'} {fmt(v, 2)}" for i, v in enumerate(it["params"])
                               if labels[i] or (v not in (0, 0.0, None)))
            unit = "°" if it["units"] == "deg" else " m"
            t.add_row(str(it["seq"]), it["command"].removeprefix("MAV_CMD_"), it["frame"].removeprefix("MAV_FRAME_"),
                      params, f"{it['x']:.7f}{unit}", f"{it['y']:.7f}{unit}", fmt(it["z"], 2),
                      ", ".join(map(str, it["frames"])))
        con.print(t)
    if args.plan:
        con.print(f"Plan written to {args.plan}")
    return ExitStatus.OK
