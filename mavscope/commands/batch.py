"""`mavscope batch FILES_OR_DIRS... [-j N] -- verify|audit|stats [OPTIONS]`: a per-capture command over
many captures, N at a time in worker processes, with one summary table (or JSON) and the worst status
of them all (2 an error > 1 findings > 0 ok).

A capture's status is decided from what its run gives: an error when the run failed; for verify and
audit their exit status (1 already means a failed verification or a finding of severity warn or error);
for stats, which always exits 0, "findings" when its JSON lists a finding of severity warn or error (notes
are information). Lines the run wrote on stderr besides (damage to the capture, no frames found) are its
*problems*: counted, the first shown."""

from __future__ import annotations

import argparse
import io
import multiprocessing
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from typing import TYPE_CHECKING, Any

import orjson

from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import console, whole_number, write_json
from mavscope.errors import UsageError

if TYPE_CHECKING:
    from mavscope.output.grid import Cell

COMMANDS = ("verify", "audit", "stats")
Outcome = tuple[int, str, str]  # exit status, stdout, stderr of one run


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("batch",
                       usage="mavscope batch FILES_OR_DIRS... [-j N] [--json] -- {verify,audit,stats} [OPTIONS]",
                       description="Run a per-capture command over every capture named (directories are "
                                   "walked), N at a time, and summarise: one row per capture. The command and "
                                   "its options (keys...) follow `--`; each capture is given to it as its FILE. "
                                   "Status per capture: error when its run failed; findings when verify or audit "
                                   "exit 1 (a failed verification; an audit finding of severity warn or error) "
                                   "or stats lists a finding of severity warn or error. Problems: the lines a run "
                                   "wrote on stderr (damage to the capture, no frames found), counted, the first "
                                   "shown. "
                                   "Exit status: the worst status (2 error > 1 findings > 0 ok); problems "
                                   "alone do not change it.")
    p.add_argument("paths", nargs="+", metavar="FILE_OR_DIR", help="captures, or directories holding them")
    p.add_argument("-j", dest="jobs", type=whole_number(1), default=1, metavar="N",
                   help="captures at a time (default 1)")
    p.add_argument("--json", action="store_true", help="the summary and each run's JSON document as one JSON")
    p.set_defaults(run=run, passthrough=None)


def run_one(argv: list[str], environ: Mapping[str, str]) -> Outcome:
    """`mavscope ARGV...` in this process, its output captured (the worker processes' task)."""
    from mavscope.cli import main

    out, err = io.StringIO(), io.StringIO()
    try:
        status = main(argv, Env(stdout=out, stderr=err, environ=dict(environ)))
    except Exception as e:  # a bug in one run must not lose the others' results
        return int(ExitStatus.ERROR), out.getvalue(), err.getvalue() + f"mavscope: internal error: {e!r}\n"
    return int(status), out.getvalue(), err.getvalue()


def worst(statuses: list[int]) -> ExitStatus:
    """ERROR over FINDINGS over OK (an interrupted run counts as an error)."""
    if any(s not in (ExitStatus.OK, ExitStatus.FINDINGS) for s in statuses):
        return ExitStatus.ERROR
    return ExitStatus.FINDINGS if ExitStatus.FINDINGS in statuses else ExitStatus.OK


def _findings(found: list[dict[str, Any]]) -> str:
    """"1 error, 2 warn [code] [code] [code]" (the first three codes) or "no findings"."""
    counts: dict[str, int] = {}
    for f in found:
        counts[f["severity"]] = counts.get(f["severity"], 0) + 1
    order = ("error", "warn", "note", "chat")
    text = ", ".join(f"{counts[s]} {s}" for s in order if s in counts) or "no findings"
    return text + "".join(f" [{f['code']}]" for f in found[:3])


def _summary(command: str, doc: dict[str, Any]) -> tuple[int | None, str]:
    """(frames, one line) of a run's JSON document."""
    if command == "verify":
        frames = sum(int(s.get("frames", 0)) for s in doc.get("streams", []))
        if doc.get("ok"):
            return frames, "ok" + ("" if doc.get("signing_in_force", True) else "; signing not in force (v1 frames)")
        return frames, f"FAIL: {doc.get('problem_count', 0)} problem(s)"
    found = doc.get("findings", [])
    if command == "audit":
        return doc.get("frames"), _findings(found)
    totals = doc.get("totals", {})
    return totals.get("frames"), (f"{totals.get('links', 0)} link(s), {totals.get('lost', 0)} lost; "
                                  + _findings(found))


def status_of(command: str, exit_status: int, doc: dict[str, Any] | None) -> int:
    """A run's status from its result: stats exits 0 whatever it found, so its findings decide, by audit's
    rule: a finding of severity warn or error (notes are information, as in Wireshark's expert info)."""
    if command == "stats" and exit_status == ExitStatus.OK and doc is not None and any(
            f.get("severity") in ("warn", "error") for f in doc.get("findings", [])):
        return int(ExitStatus.FINDINGS)
    return exit_status


def _runner(jobs: int, count: int) -> Callable[[list[list[str]], Mapping[str, str]], list[Outcome]]:
    """Runs in this process (one job, or one capture), or in `jobs` worker processes."""
    def sequential(argvs: list[list[str]], environ: Mapping[str, str]) -> list[Outcome]:
        return [run_one(a, environ) for a in argvs]

    def parallel(argvs: list[list[str]], environ: Mapping[str, str]) -> list[Outcome]:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            return list(pool.map(run_one, argvs, [environ] * len(argvs)))

    return sequential if jobs <= 1 or count <= 1 else parallel


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    rest = args.passthrough
    if not rest:
        raise UsageError("batch: give the command after --, e.g. mavscope batch DIR -- verify --key ...")
    command, options = rest[0], list(rest[1:])
    if command not in COMMANDS:
        raise UsageError(f"batch: runs {', '.join(COMMANDS)}, not {command!r}")
    from mavscope.commands.export import gather

    captures = gather(env, args.paths, ())
    if not captures:
        raise UsageError("batch: no captures among the paths given")
    if "--json" not in options:
        options.append("--json")
    argvs = [[command, path, *options] for path in captures]
    outcomes = _runner(args.jobs, len(argvs))(argvs, env.environ)
    rows = []
    for path, (status, out, err) in zip(captures, outcomes):
        doc = None
        if status in (ExitStatus.OK, ExitStatus.FINDINGS):
            try:
                doc = orjson.loads(out)
            except orjson.JSONDecodeError:
                doc = None
        if not isinstance(doc, dict):
            doc = None
        frames, text = _summary(command, doc) if doc is not None else (None, "")
        lines = [ln.removeprefix("mavscope: ").removeprefix(f"{path}: ") for ln in err.splitlines() if ln.strip()]
        problems = lines if doc is not None else []  # (a failed run's lines are its error: the summary)
        status = status_of(command, status, doc)
        rows.append({"file": path, "exit": status, "status": _status_name(status), "frames": frames,
                     "summary": text or " ".join(lines), "problems": len(problems),
                     "first_problem": problems[0] if problems else None, "result": doc, "stderr": err or None})
    status = worst([r["exit"] for r in rows])  # type: ignore[misc]
    if args.json:
        write_json(env, {"command": command, "exit": int(status), "status": _status_name(status),
                         "captures": rows})
        return status
    _render(env, command, rows, status)
    return status


def _status_name(status: int) -> str:
    return {0: "ok", 1: "findings", 2: "error"}.get(status, "error")


def _render(env: Env, command: str, rows: list[dict[str, object]], status: ExitStatus) -> None:
    from mavscope.output.console import text
    from mavscope.output.grid import Column, print_table

    con = console(env)
    # a capture's path is what a reader greps for: whole on its line where it takes up to a third of the width
    longest = max((len(str(r["file"])) for r in rows), default=0)
    cols = [Column("capture", fold=True, min_width=max(7, min(longest, con.width // 3))),
            Column("status", fold=True, key=True), Column("frames", right=True, fold=True),
            Column("summary", fold=True), Column("problems", fold=True)]

    def row(r: dict[str, object]) -> list[Cell]:
        frames, problems = r["frames"], r["problems"]
        return [text(str(r["file"])), str(r["status"]), "-" if frames is None else str(frames),
                text(str(r["summary"])), text(f"{problems} line(s): {r['first_problem']}" if problems else "-")]

    print_table(con, cols, rows, row, title=f"mavscope {command} over {len(rows)} capture(s)")
    counts = {n: sum(r["status"] == n for r in rows) for n in ("ok", "findings", "error")}
    damaged = sum(bool(r["problems"]) for r in rows)
    con.print(f"{counts['ok']} ok, {counts['findings']} with findings, {counts['error']} error(s); {damaged} with "
              f"problems on stderr; exit status {int(status)} ({_status_name(status)})", highlight=False)
