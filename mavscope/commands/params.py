"""`mavscope params FILE [--json] [--out F.param|F.params] [--diff OTHER]`: every parameter a capture shows
(PARAM_VALUE, PARAM_EXT_*, `@PARAM/param.pck` over MAVLink FTP), every set with its answer as a timeline, the
final values; export as a MAVProxy/Mission Planner `.param` or QGroundControl `.params` file; compare with
another capture or parameter file."""

from __future__ import annotations

import argparse
import os

from mavscope import __version__
from mavscope.analysis.params import (
    ParamFileError,
    ParamLog,
    ParamTracker,
    diff,
    param_file,
    params_json,
    qgc_file,
    read_param_text,
    value_text,
)
from mavscope.analysis.params.values import Value
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import add_analysis_options, analysis_pass
from mavscope.commands.common import OutputKind, add_output_option, check_outputs, console, write_json, write_output
from mavscope.errors import UsageError
from mavscope.output.grid import columns, print_table
from mavscope.output.tables import iso

MAX_TEXT_FILE = 16 * 1024 * 1024  # a parameter file larger than this is taken for a capture


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("params",
                       description="Every parameter a capture shows (PARAM_VALUE, PARAM_SET, PARAM_EXT_*, and "
                                   "@PARAM/param.pck read or written over MAVLink FTP) as a timeline: who set what, "
                                   "when, over which link, signed or not, and whether the vehicle confirmed it; "
                                   "the final values; security-relevant changes as findings (docs/analysis.md).")
    add_analysis_options(p)
    add_output_option(p, "--out", metavar="FILE", kind=OutputKind.TEXT,
                      help="write the final parameters: FILE.params in QGroundControl's format (every component of "
                           "the vehicle), anything else (and -) as a MAVProxy/Mission Planner .param (NAME,VALUE)")
    p.add_argument("--diff", metavar="OTHER",
                   help="compare the final parameters with another capture or a .param/.params file")
    p.set_defaults(run=run)


def _analyse(args: argparse.Namespace, env: Env) -> tuple[str, ParamLog, object]:
    with analysis_pass(args, env) as frames:
        tracker = ParamTracker()
        for f in frames:
            tracker.feed(f)
        return frames.session.name, tracker.finish(), frames.selection


def _param_text(path: str) -> str | None:
    """The text of `path` if it is a parameter file, else None (a capture)."""
    try:
        if os.path.getsize(path) > MAX_TEXT_FILE:
            return None
        with open(path, "rb") as fh:
            raw = fh.read(MAX_TEXT_FILE)
    except OSError as exc:
        raise UsageError(f"params: --diff {path}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return None
    try:
        read_param_text(text)
    except ParamFileError:
        return None
    return text


def _other(args: argparse.Namespace, env: Env, log: ParamLog) -> tuple[str, dict[str, Value], str]:
    """The parameters to compare with: (what they are, name -> value, which component)."""
    text = _param_text(args.diff)
    if text is not None:
        sets = read_param_text(text)
        key = log.main if log.main in sets else (None if None in sets else next(iter(sets)))
        which = "file" if key is None else f"{key[0]}/{key[1]}"
        return "parameter file", sets[key], which
    other = argparse.Namespace(**{**vars(args), "file": args.diff, "file_opt": None, "display_filter": None})
    _name, olog, _sel = _analyse(other, env)
    if not olog.final:
        raise UsageError(f"params: --diff {args.diff}: no parameter values in it (neither a parameter file nor a "
                         "capture with PARAM_VALUE, PARAM_EXT_VALUE or param.pck)")
    main = olog.main
    return "capture", olog.final, "-" if main is None else f"{main[0]}/{main[1]}"


def _export(env: Env, args: argparse.Namespace, path: str, log: ParamLog, capture: str) -> dict[str, object]:
    header = [f"written by mavscope {__version__} from {os.path.basename(capture)}"]
    if path.endswith(".params"):
        main = log.main
        comps = sorted((c for c in log.components if main is not None and c.addr[0] == main[0]),
                       key=lambda c: (c.addr != main, c.addr))
        text, left_out = qgc_file(comps, header)
        fmt, count = "qgc-params", sum(len(c.params) for c in comps)
    else:
        main = log.main
        header.append("component " + ("-" if main is None else f"{main[0]}/{main[1]}"))
        text, left_out = param_file(log.final, header)
        fmt, count = "param", len(log.final)
    if not count:
        raise UsageError(f"params: --out: {capture} holds no parameter values to write")
    write_output(env, args, "--out", path, text)
    return {"file": path, "format": fmt, "written": count - len(left_out), "left_out": left_out}


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    report = check_outputs(args, env, stdout_used="--json" if args.json else None)  # stderr's for --out -
    path, log, select = _analyse(args, env)
    doc: dict[str, object] = {"file": path, **params_json(log, select)}  # type: ignore[arg-type]
    if args.diff:
        kind, other, which = _other(args, env, log)
        doc["diff"] = {"other": args.diff, "other_kind": kind, "other_component": which, **diff(log.final, other)}
    if args.out:
        out = _export(env, args, args.out, log, path)
        doc["out"] = out
        for name in out["left_out"]:  # type: ignore[attr-defined]
            env.say(f"params: --out: {name!r} left out (a name a parameter file cannot hold)")
    if args.json:
        write_json(env, doc)
        return ExitStatus.OK
    _print(report, doc)
    return ExitStatus.OK


def _answer(e: dict) -> str:
    if e["kind"] != "set":
        return e["explanation"] or "no set explains it"
    if e["confirmed"] is True:
        return f"confirmed ({e['confirm_frame']})"
    if e["confirmed"] is False:
        return f"{e['ack'] or 'reported ' + value_text(e['reported'])} ({e['confirm_frame']})"
    return "no answer"


def _timeline_row(e: dict) -> list[str]:
    name = e["name"] + (" !" if e["security"] else "")
    return [str(e["frame"]), iso(e["time"]), e["kind"],
            f"{e['from'][0]}/{e['from'][1]} -> {e['component'][0]}/{e['component'][1]}", name,
            value_text(e["value"]), value_text(e["previous"]), e["source"], e["link"], e["signature"],
            _answer(e) + (f", {e['retries']} retries" if e["retries"] else "")]


def _print(env: Env, doc: dict) -> None:
    con = console(env)
    comps: list[dict] = doc["components"]
    if not comps and not doc["timeline"]:
        con.print(f"No parameter in {doc['file']}.", markup=False)
    for c in comps:
        sources = ", ".join(f"{k} {v}" for k, v in c["sources"].items())
        enc = f"; integers {c['encoding']} ({c['encoding_basis']})" if c["encoding"] else ""
        announced = f" (announced {c['announced_count']})" if c["announced_count"] is not None else ""
        con.print(f"Component {c['sysid']}/{c['compid']}: {c['count']} parameters{announced}; values from "
                  f"{sources}{enc}", highlight=False, markup=False)
    main = doc["main_component"]
    if main:
        con.print(f"Final values: {len(doc['final'])} parameters of {main[0]}/{main[1]} (--json, --out F.param)",
                  highlight=False, markup=False)
    for x in doc["ftp"]:
        con.print(f"FTP {x['direction']} {x['path']}: {x['size']:,} bytes, {x.get('decoded', 0)} parameters"
                  f"{'' if x['complete'] else ' (incomplete)'}; frames {x['first_frame']}-{x['last_frame']}"
                  + "".join(f"; {p}" for p in x.get("problems", [])), highlight=False, markup=False)
    if doc["timeline"]:
        print_table(con, columns("frame", "time", "kind", "from -> to", "parameter", "value", "was", "via", "link",
                                 "signature", "answer", right=("frame",)), doc["timeline"], _timeline_row,
                    title="Timeline (sets with their answer, changes with what explains them)", words=True)
        con.print(f"{doc['sets']} set(s), {doc['confirmed']} confirmed; {doc['unexplained']} change(s) nothing in "
                  "the capture explains; ! marks security-relevant parameters",
                  highlight=False, markup=False)
    if "diff" in doc:
        d = doc["diff"]
        con.print(f"Compared with {d['other']} ({d['other_kind']}, component {d['other_component']}): "
                  f"{len(d['changed'])} changed, {len(d['only_here'])} only here, {len(d['only_there'])} only there",
                  highlight=False, markup=False)
        rows = [(n, value_text(a), value_text(b)) for n, (a, b) in d["changed"].items()]
        rows += [(n, value_text(v), "-") for n, v in d["only_here"].items()]
        rows += [(n, "-", value_text(v)) for n, v in d["only_there"].items()]
        if rows:
            print_table(con, columns("parameter", "here", "there", "security"), rows,
                        lambda r: (*r, d["security"].get(r[0], "")), words=True)
    for f in doc["findings"]:
        con.print(f"[{f['severity']}] {f['code']}: {f['message']}", highlight=False, markup=False)
    if "out" in doc:
        o = doc["out"]
        con.print(f"Written {o['written']} parameters to {o['file']} ({o['format']})", highlight=False, markup=False)
