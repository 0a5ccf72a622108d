"""`mavscope track FILE --geojson|--kml|--gpx OUT`: each vehicle's track with its times, and the mission,
fence and rally points beside it."""

from __future__ import annotations

import argparse
import json

from mavscope.analysis.track import TrackBuilder
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass
from mavscope.commands.common import OutputKind, add_output_option, check_outputs, console, write_json, write_output
from mavscope.errors import UsageError
from mavscope.output.geo import geojson, gpx, kml, xsd_time
from mavscope.output.tables import iso


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("track",
                       description="Write each system's positions (GLOBAL_POSITION_INT, else GPS_RAW_INT) with their "
                                   "times, and the mission, fence and rally points the capture transferred, as "
                                   "GeoJSON (RFC 7946), KML or GPX 1.1 (docs/analysis.md).")
    add_analysis_options(p)
    out = p.add_argument_group("output (one or more)")
    add_output_option(out, "--geojson", metavar="OUT", kind=OutputKind.TEXT, help="write GeoJSON to OUT")
    add_output_option(out, "--kml", metavar="OUT", kind=OutputKind.TEXT, help="write KML to OUT")
    add_output_option(out, "--gpx", metavar="OUT", kind=OutputKind.TEXT, help="write GPX 1.1 to OUT")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    targets = [(fmt, path) for fmt, path in (("geojson", args.geojson), ("kml", args.kml), ("gpx", args.gpx)) if path]
    if not targets and not args.json:
        raise UsageError("track: say where to write: --geojson OUT, --kml OUT or --gpx OUT (or --json for a summary)")
    report = check_outputs(args, env, stdout_used="--json" if args.json else None)  # stderr's for an output -
    with analysis_pass(args, env) as frames:
        dialect, path = frames.session.dialect, frames.session.name
        builder = TrackBuilder(dialect)
        flt = frames.session.display_filter
        for frame in frames:
            if flt is None or flt.matches(frame) or frame.msgname not in ("GLOBAL_POSITION_INT", "GPS_RAW_INT"):
                builder.add(frame)
    result = builder.result()
    for fmt, out in targets:
        text = json.dumps(geojson(result, dialect), indent=1) + "\n" if fmt == "geojson" else \
            kml(result, dialect) if fmt == "kml" else gpx(result, dialect)
        write_output(env, args, f"--{fmt}", out, text)
    summary = [{"sysid": t.sysid, "compid": t.compid, "source": t.source, "positions": t.seen,
                "points": len(t.points), "every": t.stride, "start": xsd_time(t.points[0].time),
                "end": xsd_time(t.points[-1].time)} for t in result.tracks]
    plan = result.plan
    mission: dict[str, object] = {"mission_transfer": None, "fence_transfer": None, "rally_transfer": None} \
        if plan is None else {k: v for k, v in plan.json().items() if k.endswith("_transfer")}
    mission["cleared"] = {} if plan is None else plan.cleared
    mission["history_mission_transfer"] = None if result.history is None or result.history.mission is None \
        else result.history.mission + 1
    if args.json:
        write_json(env, {"file": path, "tracks": summary, **mission,
                         "written": [{"format": fmt, "file": out} for fmt, out in targets]})
        return ExitStatus.OK
    con = console(report)
    if not result.tracks:
        env.say(f"track: no positions in {path} (GLOBAL_POSITION_INT or GPS_RAW_INT with a fix)")
    for t in result.tracks:
        thin = f" (every {t.stride}th of {t.seen})" if t.stride > 1 else ""
        con.print(f"system {t.sysid}/{t.compid}: {len(t.points)} points{thin} from {t.source}, "
                  f"{xsd_time(t.points[0].time) or '-'} to {xsd_time(t.points[-1].time) or '-'}", markup=False)
    if plan is not None:
        shown = [f"{k.removesuffix('_transfer')} {v}" for k, v in mission.items() if k.endswith("_transfer")
                 and not k.startswith("history") and v is not None]
        if shown:
            con.print("mission, fence and rally: transfers " + ", ".join(shown), markup=False)
        for what, c in plan.cleared.items():
            by = f"transfer {c['transfer']}" if c["transfer"] is not None else f"event {c['event']}"
            before = c["history"]
            held = f"; it held transfer {before[-1]} before (drawn as history)" if what == "mission" and before else ""
            con.print(f"the vehicle holds no {what} since {iso(c['at'])} (frame {c['frame']}, {by}){held}",
                      markup=False)
    for fmt, out in targets:
        con.print(f"wrote {fmt} to {out}", markup=False)
    return ExitStatus.OK
