"""`mavscope stats FILE`: message rates, loss per link, conversations, totals and expert findings."""

from __future__ import annotations

import argparse
from typing import cast

from mavscope.analysis import expert_batch
from mavscope.analysis import stats as model
from mavscope.analysis.expert import Expert
from mavscope.analysis.selection import Selection
from mavscope.analysis.stats import Stats, StatsBuilder, compute_stats
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass, print_findings
from mavscope.commands.common import Problems, capture_session, console, whole_number, write_json
from mavscope.notes import Finding
from mavscope.output.grid import columns, print_table
from mavscope.output.tables import PARTIAL_MARK, fmt, iso, listed, partial_line, sparkline

SPARK_WIDTH = 40


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("stats",
                       description="Statistics over the MAVLink frames of a capture (after -Y, if given). "
                                   "Loss is counted from sequence gaps per (sysid, compid): filter by link, "
                                   "not by message, when loss matters.")
    add_analysis_options(p)
    p.add_argument("--sparklines", type=whole_number(0), default=12, metavar="N",
                   help="per-second rate sparklines for the N busiest message streams (default 12, 0: none)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    stats, findings, path, select = _compute(args, env)
    doc = stats.to_json(select)
    if args.json:
        doc["findings"] = [f.to_json() for f in findings]
        doc["file"] = path
        doc["filter"] = args.display_filter
        write_json(env, doc)
        return ExitStatus.OK
    con = console(env)
    busiest = sorted(stats.streams, key=lambda k: -stats.streams[k].count)[: max(0, args.sparklines)]
    spark = set(busiest)

    def message(m: dict) -> list[str]:
        key = (m["sysid"], m["compid"], m["msgname"])
        line = sparkline(stats.rate_series(key, SPARK_WIDTH)) if key in spark else ""
        rate = "burst" if m["burst"] else fmt(m["rate_hz"], 2)
        return [f"{m['sysid']}/{m['compid']}", str(m["msgname"]), str(m["count"]), rate, str(m["bytes"]), line]

    def link(lk: dict) -> list[str]:
        mark = PARTIAL_MARK if lk["logged_in_part"] else ""
        return [f"{lk['sysid']}/{lk['compid']}", str(lk["received"]), str(lk["lost"]) + mark,
                fmt(lk["loss_pct"], 2) + mark,
                str(lk["duplicates"]), str(lk["reordered"]), str(lk["v1"]), str(lk["v2"]),
                _counts(lk["crc"]), _counts(lk["signature"]), listed(lk["endpoints"])]

    def conversation(c: dict) -> list[str]:
        return [str(c["transport"]), str(c["a"]), str(c["b"]) or "-", str(c["frames"]), str(c["frames_a_to_b"]),
                str(c["frames_b_to_a"]), str(c["bytes"]), iso(c["start"]), fmt(c["duration"]),
                listed([f"{s}/{k}" for s, k in cast("list[list[int]]", c["systems"])])]

    print_table(con, columns("sysid/compid", "message", "count", "rate Hz", "bytes", "rate per second",
                             right=("sysid/compid", "count", "rate Hz", "bytes")),
                cast("list[dict]", doc["messages"]), message, title=f"Messages ({path})")
    print_table(con, columns("sysid/compid", "received", "lost", "loss %", "dup", "late", "v1", "v2", "CRC",
                             "signature", "endpoints",
                             right=("sysid/compid", "received", "lost", "loss %", "dup", "late", "v1", "v2")),
                cast("list[dict]", doc["links"]), link, title="Links (sysid, compid)")
    partial = partial_line(cast("list[dict]", doc["links"]))
    if partial:
        con.print(partial, highlight=False, markup=False)
    print_table(con, columns("transport", "A", "B", "frames", "A→B", "B→A", "bytes", "start", "duration s", "systems",
                             right=("frames", "A→B", "B→A", "bytes", "duration s")),
                cast("list[dict]", doc["conversations"]), conversation, title="Conversations")

    tot = cast("dict", doc["totals"])
    shown = f" (-Y matched {tot['matched']}; rows with a matched frame shown)" if "matched" in tot else ""
    con.print(f"Totals{shown}: {tot['frames']} frames, {tot['bytes']} bytes, {fmt(tot['duration'])} s, "
              f"{tot['links']} links, {tot['messages']} message types, {_lost(tot)}; "
              f"v1 {tot['v1']}, v2 {tot['v2']}; CRC {_counts(tot['crc'])}; "
              f"signature {_counts(tot['signature'])}")
    for key, rows, what, limit in (
            ("unfollowed_stream_frames", "Messages", "(sender, message) streams", model.MAX_STREAMS),
            ("unfollowed_conversation_frames", "Conversations", "conversations", model.MAX_CONVERSATIONS)):
        if tot[key]:
            con.print(f"{tot[key]:,} frames are not in the {rows} table: their {what} came after the first "
                      f"{limit:,} (the totals and the links count them)")
    print_findings(con, findings)
    return ExitStatus.OK


def _compute(args: argparse.Namespace, env: Env) -> tuple[Stats, list[Finding], str, Selection]:
    """The statistics and the findings (those about a selected frame), the capture's name, the selection.

    Without a display filter every frame goes in column batches (`Session.batches`); a filter must see
    every frame as a Frame, which `analysis_pass` gives."""
    if args.display_filter:
        with analysis_pass(args, env) as frames:
            expert = Expert(frames.session.dialect)
            stats = compute_stats(frames, expert)
            path, select = frames.session.name, frames.selection
        return stats, [f for f in expert.findings() if select.any_record(f.frames)], path, select
    builder = StatsBuilder()
    with capture_session(args, env) as session:
        expert = Expert(session.dialect)
        problems = Problems(env, session.name)
        try:
            for b in session.batches(problems.item):
                expert_batch.feed(expert, b, builder.add_batch(b))
        finally:
            problems.close()
        path = session.name
    stats = builder.result()
    stats.logged_in_part = expert.logged_in_part()
    return stats, expert.findings(), path, Selection()


def _lost(tot: dict) -> str:
    """The totals' loss: on the links, and apart the numbers missing from ground stations' own frames in a tlog."""
    part = tot["lost_logged_in_part"]
    if not part:
        return f"{tot['lost']} lost"
    return (f"{tot['lost'] - part} lost on the links ({part} more missing from ground stations' own frames, "
            f"which a tlog logs only in part{PARTIAL_MARK})")


def _counts(d: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in d.items()) or "-"
