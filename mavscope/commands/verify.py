"""`mavscope verify FILE --key ...`: signature verdicts per stream; exit 1 on any invalid, replayed or
injected unsigned frame (a gate for CI pipelines and flight-log intake). The counting is
`mavscope.security.verify`; this module renders it."""

from __future__ import annotations

import argparse

from mavscope.cli import Env, ExitStatus
from mavscope.commands.analysis_common import Pass
from mavscope.commands.common import (
    add_capture_options,
    add_key_options,
    capture_session,
    console,
    pipeline_options,
    write_json,
)
from mavscope.errors import UsageError
from mavscope.mavlink.frame import frame_number
from mavscope.output.grid import columns, print_table
from mavscope.security.verify import StreamRow, VerifyReport

SHOWN = 20


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("verify",
                       description="Check every signed frame against the supplied keys (docs/security.md). "
                                   "Exit status: 0 every check passed, 1 an invalid, replayed or injected "
                                   "unsigned frame, 2 bad usage or an unreadable file.")
    add_capture_options(p)
    add_key_options(p)
    p.add_argument("--json", action="store_true", help="print the per-stream table as JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if not pipeline_options(args, env).has_key_material:
        raise UsageError("verify: no key material: give --key (or --ecdh-private, --use-leaked-keys, "
                         "MAVSCOPE_KEYRING)")
    report = VerifyReport()
    with capture_session(args, env) as session:
        for f in Pass(session, env):  # (damage and anomalies on stderr, as read says them)
            report.add(f)
        path = session.name
    report.finish()
    status = ExitStatus.FINDINGS if report.failed else ExitStatus.OK
    if args.json:
        write_json(env, {"file": path, "ok": not report.failed, "signing_in_force": not report.v1_frames,
                         "streams": [report.rows[k].to_json(*k) for k in sorted(report.rows)],
                         "problems": [{"frame": r, "index": i, "message": m} for r, i, m in report.problems],
                         "problem_count": report.problem_count})
    else:
        _render(env, path, report)
    return status


def _skew_text(r: StreamRow) -> str:
    if not r.skew:
        return "-"
    return f"{min(r.skew):+.3f}" + (f"..{max(r.skew):+.3f}" if len(r.skew) > 1 else "")


def _render(env: Env, path: str, report: VerifyReport) -> None:
    con = console(env)

    def row(item: tuple[tuple[int, int], StreamRow]) -> list[str]:
        (sysid, compid), r = item
        return [f"{sysid}/{compid}", ",".join(map(str, sorted(r.links))) or "-", str(r.frames), str(r.signed),
                str(r.valid), str(r.invalid), str(r.replay), str(r.no_key), str(r.unsigned), str(r.injected),
                str(r.v1), ",".join(sorted(r.keys)) or "-", _skew_text(r)]

    names = ("sysid/compid", "links", "frames", "signed", "valid", "invalid", "replay", "no-key", "unsigned",
             "injected", "v1", "keys", "skew s")
    print_table(con, columns(*names, right=[n for n in names if n not in ("links", "keys")]),
                sorted(report.rows.items()), row, title=f"Signatures ({path})")
    for record, index, message in report.problems[:SHOWN]:
        con.print(f"frame {frame_number(record, index)}: {message}", highlight=False)
    if report.problem_count > SHOWN:
        con.print(f"... and {report.problem_count - SHOWN} more", highlight=False)
    if report.v1_frames:
        con.print(f"WARNING: signing is not in force: {report.v1_frames} MAVLink v1 frame(s) from senders that sign "
                  "(v1 cannot carry a signature: a downgrade-capable link)", highlight=False)
    if report.failed:
        verdict = "FAIL: invalid, replayed or injected frames"
    elif report.all_checked:
        verdict = "OK: every signed frame verified"
    else:
        verdict = "OK: no invalid, replayed or injected frame (some signed frames had no key)"
    con.print(verdict, highlight=False)
