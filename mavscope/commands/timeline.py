"""`mavscope timeline FILE`: the clocks of each system side by side with capture time."""

from __future__ import annotations

import argparse

from mavscope.analysis import timeline as clocks
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass
from mavscope.commands.common import console, write_json
from mavscope.output.grid import columns, many, print_lines, print_table
from mavscope.output.tables import fmt, iso


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("timeline",
                       description="Compare every clock a capture reveals with capture time: offset, drift and "
                                   "round-trip times.")
    add_analysis_options(p)
    p.set_defaults(run=run)


def _drift(clock: dict) -> str:
    """"+250.0 ± 3.1", or "-" where the samples are too few or too close together to measure a drift."""
    if clock["drift_ppm"] is None:
        return "-"
    err = clock["drift_err_ppm"]
    return f"{clock['drift_ppm']:+.1f}" + (f" ± {err:.1f}" if err is not None else "")


def _clock_row(c: dict) -> list[str]:
    return [str(c["component"]), c["source"], c["kind"], str(c["samples"]),
            f"{c['offset_s']:+.6f}" if c["kind"] == "unix" else "-", _drift(c), fmt(c["jitter_ms"]),
            iso(c.get("zero_at"))]


def _restarts(c: dict) -> str:
    at = ", ".join(iso(x) for x in c["restarted_at"][:3]) + (" ..." if c["restarts"] > 3 else "")
    return (f"  {c['source']} of component {c['component']} restarted {c['restarts']} time(s) (at {at}): offset, "
            "drift and zero are those of its last run")


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    with analysis_pass(args, env) as frames:
        path, select = frames.session.name, frames.selection
        timeline = clocks.reconstruct(frames)
    doc = timeline.to_json(select)
    if args.json:
        doc["file"] = path
        write_json(env, doc)
        return ExitStatus.OK
    con = console(env)
    con.print(f"Capture {path}: {iso(doc['start'])} to {iso(doc['end'])} ({fmt(doc['duration'])} s); "  # type: ignore[arg-type]
              "offsets are clock minus capture time at the first frame")
    systems: list[dict] = doc["systems"]  # type: ignore[assignment]
    plain = many(sum(len(s["clocks"]) + len(s["round_trips"]) for s in systems))  # a layout for every table
    for s in systems:
        print_table(con, columns("comp", "clock", "kind", "samples", "offset s", "drift ppm", "jitter ms",
                                 "reads zero at", right=("comp", "samples", "offset s", "drift ppm", "jitter ms")),
                    s["clocks"], _clock_row, title=f"System {s['sysid']}", plain=plain)
        print_lines(con, (_restarts(c) for c in s["clocks"] if c["restarts"]), plain=plain)
        print_lines(con, (f"  {r['kind']} round trips to system {r['peer']}: {r['count']}, min {r['min_ms']:.3f} ms, "
                          f"mean {r['mean_ms']:.3f} ms, max {r['max_ms']:.3f} ms" for r in s["round_trips"]),
                    plain=plain)
    print_lines(con, (f"[{f['severity']}] capacity: {f['message']}" for f in doc["findings"]),  # type: ignore[attr-defined]
                plain=plain)
    if doc["unfollowed_readings"]:
        con.print(f"{doc['unfollowed_readings']:,} readings of clocks beyond the first {clocks.MAX_CLOCKS:,} were not "
                  "followed")
    if not doc["systems"]:
        con.print("No clock information (the capture has no timestamps or no timed messages).")
    return ExitStatus.OK
