"""`mavscope audit FILE`: security findings (leaked keys, replays, forged and injected frames, weak
passphrases, fixed keystreams) as a list, or `{"findings": [...]}` with --json.

One pass serves every finding: the audit's own and every security-group finding of the expert detectors,
the very pass `stats` runs (mavscope.analysis.expert), put together by mavscope.analysis.audit_pass (the
one implementation the export's findings table uses too), with the detection rules: the shipped pack unless
--no-default-rules, and the files of --rules (docs/rules.md)."""

from __future__ import annotations

import argparse

from mavscope.analysis.audit_pass import AuditPass
from mavscope.analysis.expert import Expert
from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import Pass
from mavscope.commands.common import add_capture_options, add_key_options, capture_session, write_json
from mavscope.errors import UsageError
from mavscope.mavlink.dialect import load_dialect
from mavscope.notes import Severity, finding_line
from mavscope.rules import rule_set
from mavscope.security.keystream import parse_known_plaintext
from mavscope.security.passphrase import read_wordlist

RECOVERED_SHOWN = 10


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("audit",
                       description="Security findings of a capture (docs/security.md). Exit status 1 when a "
                                   "finding of severity warn or error is reported, 0 otherwise, 2 on bad usage.")
    add_capture_options(p)
    add_key_options(p)
    p.add_argument("--wordlist", metavar="FILE", help="try every line as the signing passphrase (SHA-256)")
    p.add_argument("--qgc", action="store_true",
                   help="with --wordlist, also try QGroundControl's PBKDF2 derivation (600000 iterations: slow)")
    p.add_argument("--known-plaintext", action="append", default=[], metavar="MSG=HEX",
                   help="a guessed plaintext payload of message MSG, to recover a fixed keystream")
    p.add_argument("--rules", action="append", default=[], metavar="RULES",
                   help="detection rules: a TOML file, or a directory (its *.toml files) (docs/rules.md); may be "
                        "given more than once")
    p.add_argument("--no-default-rules", action="store_true", help="without the shipped pack of detection rules")
    p.add_argument("--json", action="store_true", help='print {"findings": [...]}')
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if args.qgc and not args.wordlist:
        raise UsageError("audit: --qgc needs --wordlist")
    dialect = load_dialect(args.dialect)
    known = tuple(parse_known_plaintext(s, dialect) for s in args.known_plaintext)
    words = None
    if args.wordlist:
        try:
            with open(args.wordlist, "rb"):
                pass  # refuse an unreadable wordlist before reading the capture
        except OSError as exc:
            raise UsageError(f"audit: --wordlist {args.wordlist}: {exc.strerror or exc}") from None
        words = read_wordlist(args.wordlist)
    rules = rule_set(dialect, args.rules, default=not args.no_default_rules)  # (refused before the capture is read)
    audit, expert = AuditPass(dialect, story=True, rules=rules), Expert(dialect)
    with capture_session(args, env, dialect) as session:
        for frame in Pass(session, env, audit.anomaly):  # (damage and anomalies on stderr, as read says them)
            audit.add(frame, expert.add(frame))  # the fields the expert decoded, decoded once
        frames = session.frame_count
    findings, recoveries = audit.result(expert.findings(), words=words, qgc=args.qgc, known=known)
    status = ExitStatus.FINDINGS if any(f.severity >= Severity.WARN for f in findings) else ExitStatus.OK
    if args.json:
        doc: dict[str, object] = {"frames": frames, "findings": [f.to_json() for f in findings]}
        if recoveries:
            doc["recovered"] = [{"frame": r.record, "msgname": r.msgname, "bytes": r.recovered.hex(),
                                 "length": r.length, "fields": r.fields} for r in recoveries]
        write_json(env, doc)
        return status
    out = env.stdout
    if not findings:
        out.write("no findings\n")
    for f in findings:
        out.write(finding_line(f) + "\n")
    if recoveries:
        out.write(f"\nRecovered without the key ({len(recoveries)} frames; first {RECOVERED_SHOWN}):\n")
        for r in recoveries[:RECOVERED_SHOWN]:
            text = f"  frame {r.record} {r.msgname}: {len(r.recovered)}/{r.length} bytes {r.recovered.hex(' ')}"
            if r.fields is not None:
                text += "\n      " + " ".join(f"{k}={v}" for k, v in r.fields.items())
            out.write(text + "\n")
    return status
