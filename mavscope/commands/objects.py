"""`mavscope objects FILE [--out DIR]`: every file moved over MAVLink FTP (both directions, and directory
listings), every log downloaded with LOG_REQUEST_DATA and every image sent as ENCAPSULATED_DATA, rebuilt
from the frames; with --out, written into DIR with a manifest.json."""

from __future__ import annotations

import argparse

import orjson

from mavscope import __version__
from mavscope.analysis.objects import Limits, ObjectTracker, objects_json, party
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass
from mavscope.commands.common import OutputKind, add_output_option, check_outputs, console, write_json
from mavscope.errors import UsageError
from mavscope.output.grid import columns, many, print_lines, print_table
from mavscope.output.objects_out import ObjectWriter
from mavscope.output.tables import iso
from mavscope.visible import quoted

MIB = 1024 * 1024
DEFAULTS = Limits()


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("objects",
                       description="Rebuild every object a capture moved: files read and written over MAVLink "
                                   "FTP and directory listings, logs downloaded with LOG_REQUEST_DATA/LOG_DATA, "
                                   "images sent as ENCAPSULATED_DATA; offsets honoured, retries and NAKs "
                                   "handled, gaps kept as gaps (docs/analysis.md).")
    add_analysis_options(p)
    add_output_option(p, "--out", metavar="DIR", kind=OutputKind.DIRECTORY,
                      help="write each object and DIR/manifest.json (DIR is created if missing)")
    p.add_argument("--max-object-mb", type=int, default=DEFAULTS.max_object // MIB, metavar="N",
                   help="keep at most N MiB of one object (default %(default)s)")
    p.add_argument("--max-memory-mb", type=int, default=DEFAULTS.max_total // MIB, metavar="N",
                   help="hold at most N MiB of object data at once (default %(default)s)")
    p.add_argument("--max-holes-mb", type=int, default=DEFAULTS.max_holes // MIB, metavar="N",
                   help="fill at most N MiB of holes (bytes never received) with zeros, all objects together "
                        "(default %(default)s)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if min(args.max_object_mb, args.max_memory_mb, args.max_holes_mb) < 1:
        raise UsageError("objects: --max-object-mb, --max-memory-mb and --max-holes-mb must be at least 1")
    check_outputs(args, env)  # (a directory: never -)
    limits = Limits(max_object=args.max_object_mb * MIB, max_total=args.max_memory_mb * MIB,
                    max_holes=args.max_holes_mb * MIB)
    writer = ObjectWriter(args.out) if args.out else None
    files: dict[int, str] = {}
    pngs: dict[int, tuple[str | None, str | None]] = {}  # image -> (its PNG's name, why none)
    try:
        with analysis_pass(args, env) as frames:
            path, select = frames.session.name, frames.selection
            tracker = ObjectTracker(limits)
            tracker.use_dialect(frames.session.dialect)

            def drain() -> None:
                for rec in tracker.take():
                    if writer is not None and select.any_record(rec.frames):
                        files[rec.number] = writer.write(rec)
                        if (png := writer.write_png(rec)) != (None, None):
                            pngs[rec.number] = png

            for f in frames:
                tracker.feed(f)
                if tracker.finished_waiting:
                    drain()
            log = tracker.finish()
            drain()
        doc = objects_json(log, files, select, pngs)
        if writer is not None:
            manifest = {"file": path, "generated_by": f"mavscope {__version__}", **doc}
            writer.write_manifest(orjson.dumps(manifest, option=orjson.OPT_INDENT_2 | orjson.OPT_APPEND_NEWLINE))
    finally:
        if writer is not None:
            writer.close()
    if args.json:
        write_json(env, {"file": path, "out": args.out, **doc})
        return ExitStatus.OK
    _print(env, path, doc, args.out)
    return ExitStatus.OK


def _signatures(sig: dict[str, dict[str, int]]) -> str:
    total: dict[str, int] = {}
    for per in sig.values():
        for k, n in per.items():
            total[k] = total.get(k, 0) + n
    return ", ".join(f"{k} {n}" for k, n in sorted(total.items()))


def _state(o: dict) -> str:
    if o["complete"]:
        return "complete"
    gaps = o["gaps"]
    missing = sum(b - a for a, b in gaps)
    unit = "entries" if o["gap_unit"] == "entries" else "bytes"
    text = f"GAPS: {missing:,} {unit} in {len(gaps)}" if gaps else "INCOMPLETE"
    return text if o["end_known"] else text + ", end unknown"


def _operation(op: dict) -> str:
    what = op["opcode"] + (f" {quoted(op['path'])}" if op["path"] else "") + (
        f" -> {quoted(op['new_path'])}" if op["new_path"] else "")  # (the Console escapes them, once)
    return (f"FTP {what} from {op['client'][0]}/{op['client'][1]}: {op['result'] or 'no answer'}"
            f"{'; ' + op['detail'] if op['detail'] else ''} (frame {op['frame']})")


def _print(env: Env, path: str, doc: dict, out: str | None) -> None:
    con = console(env)
    objs: list[dict] = doc["objects"]
    if not objs:
        con.print(f"No object (MAVLink FTP file, log or image) in {path}.", markup=False)
    else:
        names = ["#", "kind", "path / name", "from -> to", "size", "state", "frames", "signatures", "sha256"]

        def row(o: dict) -> list[str]:
            frames = f"{o['frame_count']} ({o['first_frame']}-{o['last_frame']})"
            sender = tuple(o["sender"]) if o["sender"] else None
            receiver = tuple(o["receiver"]) if o["receiver"] else None
            cells = [str(o["number"]), f"{o['kind']} {'↓' if o['direction'] == 'download' else '↑'}",
                     o["path"] or o["name"], f"{party(sender)} -> {party(receiver)}", f"{o['size']:,}", _state(o),
                     frames, _signatures(o["signatures"]), o["sha256"][:16]]
            if out:
                cells.append((o["file"] or "-") + (f" + {o['png']}" if o.get("png") else ""))
            return cells

        print_table(con, columns(*names, *(["file"] if out else []), right=("#", "size")), objs, row,
                    title=f"Objects in {path}", words=True)
        s = doc["summary"]
        con.print(f"{s['objects']} object(s), {s['complete']} complete, {s['bytes']:,} bytes; started "
                  f"{iso(objs[0]['start'])}", highlight=False, markup=False)
    print_lines(con, (_operation(op) for op in doc["operations"]), plain=many(len(doc["operations"])))
    orphans = doc["image_orphans"]["frames"]
    if orphans:
        con.print(f"{orphans} ENCAPSULATED_DATA frame(s) with no image announced before them (not kept)",
                  highlight=False, markup=False)
    for f in doc["findings"]:
        con.print(f"[{f['severity']}] {f['code']}: {f['message']}", highlight=False, markup=False)
    if out:
        con.print(f"Written to {out}/ (manifest.json)", highlight=False, markup=False)
