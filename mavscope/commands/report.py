"""`mavscope report FILES... -o report.html [--json report.json] [--params-file F] [key options]`: one
self-contained HTML page (and a JSON document with the same facts) an investigator can hand over: the
chain of custody, a summary, the findings (`audit --json`'s), the evidence sections (docs/report.md).

Each capture is read once (mavscope.report.collect); its pipeline is the one every command's options ask
for (commands.common.capture_session), its findings those `audit` gives with the same options."""

from __future__ import annotations

import argparse
import os
import time

from mavscope.analysis.params import ParamFileError, read_param_text
from mavscope.analysis.params.values import Value
from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import (
    OutputKind,
    Problems,
    add_dialect_option,
    add_key_options,
    add_output_option,
    capture_session,
    check_outputs,
    write_output,
)
from mavscope.errors import UsageError
from mavscope.mavlink.dialect import load_dialect
from mavscope.report import custody as coc
from mavscope.report.collect import collect
from mavscope.report.model import document, input_doc, json_text
from mavscope.report.summary import Names
from mavscope.rules import rule_set
from mavscope.security.keys import KEYRING_ENV

MAX_PARAM_FILE = 16 * 1024 * 1024
KEY_OPTIONS = (("key", "--key"), ("cipher", "--cipher"), ("ecdh_private", "--ecdh-private"),
               ("wifi_key", "--wifi-key"))


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report",
                       description="One self-contained, offline HTML page of one or more captures: chain of "
                                   "custody (names, sizes, SHA-256, dialects, keys by name), a summary (vehicles, "
                                   "ground stations, commands, signing, findings), the events, a map, plots, "
                                   "missions, parameters, files moved over FTP and the links (docs/report.md).")
    p.add_argument("files", nargs="+", metavar="FILE", help="capture files (pcap, pcapng, tlog, raw)")
    add_output_option(p, "-o", "--out", metavar="REPORT.html", kind=OutputKind.TEXT, help="write the HTML report")
    add_output_option(p, "--json", metavar="REPORT.json", kind=OutputKind.TEXT,
                      help="write the same facts as one JSON document (docs/report.schema.json)")
    p.add_argument("--rules", action="append", default=[], metavar="RULES",
                   help="detection rules of a TOML file or directory, as `audit --rules` (docs/rules.md)")
    p.add_argument("--no-default-rules", action="store_true", help="without the shipped pack of detection rules")
    p.add_argument("--params-file", metavar="FILE",
                   help="compare each capture's final parameters with this .param or .params file")
    add_dialect_option(p)
    add_key_options(p)
    p.set_defaults(run=run)


def _param_file(path: str) -> tuple[str, dict[str, Value]]:
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_PARAM_FILE + 1)
    except OSError as exc:
        raise UsageError(f"report: --params-file {path}: {exc.strerror or exc}") from None
    try:
        if len(raw) > MAX_PARAM_FILE:
            raise ParamFileError(f"larger than {MAX_PARAM_FILE:,} bytes")
        sets = read_param_text(raw.decode("utf-8"))
    except (UnicodeDecodeError, ParamFileError) as exc:
        raise UsageError(f"report: --params-file {path}: not a .param or .params file ({exc})") from None
    if not sets:
        raise UsageError(f"report: --params-file {path}: no parameters in it")
    key = None if None in sets else min(k for k in sets if k is not None)
    return os.path.basename(path), sets[key]


def _command_line(args: argparse.Namespace) -> list[str]:
    """The command line as run, the key options by name only (a secret is never written)."""
    words = ["mavscope", "report", *args.files]
    if args.out:
        words += ["-o", args.out]
    if args.json:
        words += ["--json", args.json]
    if args.params_file:
        words += ["--params-file", args.params_file]
    for d in args.dialect:
        words += ["--dialect", d]
    for r in args.rules:
        words += ["--rules", r]
    if args.no_default_rules:
        words.append("--no-default-rules")
    for dest, flag in KEY_OPTIONS:
        for name in coc.key_names(getattr(args, dest)):
            words += [flag, name]
    if args.use_leaked_keys:
        words.append("--use-leaked-keys")
    return words


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if not args.out and not args.json:
        raise UsageError("report: say where to write: -o REPORT.html, --json REPORT.json, or both")
    for option, out in (("-o", args.out), ("--json", args.json)):
        for path in args.files:
            if out and out != "-" and os.path.exists(out) and os.path.exists(path) and os.path.samefile(out, path):
                raise UsageError(f"report: {option} {out} is a capture being read")
    report_env = check_outputs(args, env)
    other = _param_file(args.params_file) if args.params_file else None
    dialect = load_dialect(args.dialect)
    rules = rule_set(dialect, args.rules, default=not args.no_default_rules)  # (refused before a capture is read)
    names = Names(dialect)
    inputs = []
    started = coc.now_utc()
    t0 = time.perf_counter()
    for path in args.files:
        file = coc.file_hash(path)
        one = argparse.Namespace(**{**vars(args), "file": path, "file_opt": None, "command": "report"})
        with capture_session(one, env, dialect) as session:
            problems = Problems(env, session.name)
            try:
                got = collect(session, problems.item, rules)
            finally:
                problems.close()
            inputs.append(input_doc(got, file, session.reader.kind, session.engine, names, other))
    custody = {
        "tool": coc.tool(), "analysed_at": started, "command_line": _command_line(args),
        "inputs": [i["file"] for i in inputs],
        "dialects": coc.dialect_files(dialect),
        "keys": {flag: coc.key_names(getattr(args, dest)) for dest, flag in KEY_OPTIONS},
        "use_leaked_keys": bool(args.use_leaked_keys),
        "keyring": env.environ.get(KEYRING_ENV) or None,  # (its path: the keys in it are named, never shown)
        "params_file": coc.file_hash(args.params_file).to_json() if args.params_file else None,
        "rules": coc.rule_files(args.rules, default=not args.no_default_rules),
    }
    doc = document(custody, inputs)
    if args.out:
        from mavscope.report.html import render

        write_output(env, args, "-o", args.out, render(doc))
    if args.json:
        write_output(env, args, "--json", args.json, json_text(doc))
    written = " and ".join(w for w in (args.out, args.json) if w)
    report_env.say(f"report: {len(inputs)} capture(s) in {time.perf_counter() - t0:.1f} s: wrote {written}")
    return ExitStatus.OK
