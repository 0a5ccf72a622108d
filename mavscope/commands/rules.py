"""`mavscope rules list` (the shipped pack and the files of --rules: id, severity, title, references) and
`mavscope rules check FILE...` (each file read and every filter compiled: the problems with their file and
line, exit 2; else one line per file). docs/rules.md."""

from __future__ import annotations

import argparse

from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import add_dialect_option, write_json
from mavscope.errors import UsageError
from mavscope.mavlink.dialect import load_dialect
from mavscope.rules import Rule, RuleSet, load_rules, read_file
from mavscope.rules.loader import rule_files
from mavscope.visible import visible


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("rules", description="Detection rules (docs/rules.md): list the shipped pack, check a file.")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    ls = actions.add_parser("list", help="the rules audit runs: id, severity, title, references")
    ls.add_argument("--rules", action="append", default=[], metavar="RULES",
                    help="list the rules of this TOML file or directory too")
    ls.add_argument("--no-default-rules", action="store_true", help="without the shipped pack")
    ls.add_argument("--json", action="store_true", help='print {"rules": [...]}')
    check = actions.add_parser("check", help="validate rule files: TOML, keys, and every filter compiled")
    check.add_argument("files", nargs="+", metavar="FILE|DIR")
    for q in (ls, check):
        add_dialect_option(q)
    p.set_defaults(run=run)


def _json(r: Rule) -> dict[str, object]:
    w = r.when
    when = {k: v for k, v in (("armed", w.armed), ("in_flight", w.in_flight), ("unsigned", w.unsigned),
                              ("mode", list(w.modes) or None), ("sender", w.sender.value if w.sender else None))
            if v is not None}
    out: dict[str, object] = {"id": r.id, "title": r.title, "severity": r.severity.value, "filter": r.filter,
                              "references": list(r.references), "explanation": r.explanation,
                              "remediation": r.remediation, "when": when, "source": r.source, "line": r.line}
    if r.threshold is not None:
        out["threshold"] = {"count": r.threshold.count, "window": r.threshold.window, "per": r.threshold.per.value}
    return out


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if args.action is None:
        raise UsageError("rules: an action is required (mavscope rules list, mavscope rules check FILE)")
    dialect = load_dialect(args.dialect)
    out = env.stdout
    if args.action == "check":
        for path in args.files:
            files = rule_files(path)
            if not files:
                raise UsageError(f"rules check: {path}: no *.toml file")
            for f in files:
                rules = read_file(f)
                RuleSet(rules, dialect)  # every filter compiled (RuleError with its line and caret)
                out.write(visible(f"{f}: {len(rules)} rule{'s' if len(rules) != 1 else ''}, OK") + "\n")
        return ExitStatus.OK
    rules = load_rules(args.rules, default=not args.no_default_rules)
    RuleSet(rules, dialect)
    if args.json:
        write_json(env, {"rules": [_json(r) for r in rules]})
        return ExitStatus.OK
    for r in rules:
        out.write(visible(f"{r.id}  [{r.severity.value}]  {r.title}") + "\n")
        for ref in r.references:
            out.write(visible(f"    {ref}") + "\n")
    out.write(f"{len(rules)} rule{'s' if len(rules) != 1 else ''}\n")
    return ExitStatus.OK
