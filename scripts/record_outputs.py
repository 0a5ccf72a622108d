"""Record what mavscope answers on every bundled and real capture, and compare two recordings.

Issue 36 (one engine) changes how every answer is computed, not the answers: before the change the
outputs are recorded, after it they are compared, and each difference is either explained by a fix an
issue asked for (listed in the stop's note) or a regression.

    python scripts/record_outputs.py record DIR [--real ../shared/real-captures] [--pure]
    python scripts/record_outputs.py compare OLD_DIR NEW_DIR

`record` runs each command of COMMANDS on each capture of `captures/` and of the real captures (read
there, never copied), in a fresh process with the default dialect, and writes its stdout, stderr and exit
status to DIR/<capture>/<command>.{out,err,rc}. DIR is best kept outside the repository (the outputs of
the real captures are theirs). `--pure` sets MAVSCOPE_PURE=1. `compare` prints every file that differs
(a unified diff of its first lines) and exits 1 if any does.
"""

from __future__ import annotations

import argparse
import difflib
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CAPTURE_SUFFIXES = {".pcap", ".pcapng", ".tlog", ".raw", ".bin"}

# name -> the arguments after `mavscope`; FILE is the capture
COMMANDS: dict[str, list[str]] = {
    "read-jsonl": ["read", "FILE", "-T", "jsonl"],
    "read-summary": ["read", "FILE"],
    "read-V": ["read", "FILE", "-V"],
    "stats": ["stats", "FILE"],
    "stats-json": ["stats", "FILE", "--json"],
    "audit": ["audit", "FILE"],
    "mission": ["mission", "FILE"],
    "commands": ["commands", "FILE"],
    "events": ["events", "FILE"],
    "params-json": ["params", "FILE", "--json"],
}


def captures(real: Path | None) -> list[Path]:
    found = sorted(p for p in (ROOT / "captures").iterdir() if p.suffix in CAPTURE_SUFFIXES)
    if real is not None and real.is_dir():
        found += sorted(p for p in real.iterdir() if p.suffix in CAPTURE_SUFFIXES)
    return found


def record(out: Path, real: Path | None, pure: bool) -> int:
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    env.pop("MAVSCOPE_PURE", None)
    if pure:
        env["MAVSCOPE_PURE"] = "1"
    exe = [sys.executable, "-m", "mavscope"]
    for cap in captures(real):
        where = out / cap.name
        where.mkdir(parents=True, exist_ok=True)
        for name, args in COMMANDS.items():
            argv = [str(cap) if a == "FILE" else a for a in args]
            done = subprocess.run(exe + argv, capture_output=True, env=env, cwd=ROOT, timeout=900)
            (where / f"{name}.out").write_bytes(done.stdout.replace(str(cap).encode(), b"FILE"))
            (where / f"{name}.err").write_bytes(done.stderr.replace(str(cap).encode(), b"FILE"))
            (where / f"{name}.rc").write_text(f"{done.returncode}\n")
        print(f"recorded {cap.name}", file=sys.stderr)
    return 0


def compare(old: Path, new: Path) -> int:
    differ = 0
    names = sorted({p.relative_to(old) for p in old.rglob("*") if p.is_file()}
                   | {p.relative_to(new) for p in new.rglob("*") if p.is_file()})
    for rel in names:
        a, b = old / rel, new / rel
        if not a.exists() or not b.exists():
            print(f"only in {'new' if b.exists() else 'old'}: {rel}")
            differ += 1
            continue
        if a.read_bytes() == b.read_bytes():
            continue
        differ += 1
        a_lines, b_lines = a.read_text(errors="replace").splitlines(), b.read_text(errors="replace").splitlines()
        if len(a_lines) + len(b_lines) > 20_000:  # difflib is quadratic: the first lines that differ, and counts
            first = next((i for i, (x, y) in enumerate(zip(a_lines, b_lines)) if x != y), min(len(a_lines),
                                                                                              len(b_lines)))
            print(f"--- {a}\n+++ {b}\n{len(a_lines)} and {len(b_lines)} lines; first difference at line {first + 1}:")
            print("\n".join(f"-{x}\n+{y}" for x, y in zip(a_lines[first:first + 3], b_lines[first:first + 3])))
            continue
        lines = list(difflib.unified_diff(a_lines, b_lines, str(a), str(b), lineterm="", n=1))
        print("\n".join(lines[:40]) + (f"\n... {len(lines) - 40} more diff lines" if len(lines) > 40 else ""))
    print(f"{differ} of {len(names)} files differ", file=sys.stderr)
    return 1 if differ else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("dir", type=Path)
    rec.add_argument("--real", type=Path, default=ROOT.parent / "shared" / "real-captures")
    rec.add_argument("--pure", action="store_true")
    cmp_ = sub.add_parser("compare")
    cmp_.add_argument("old", type=Path)
    cmp_.add_argument("new", type=Path)
    args = ap.parse_args(argv)
    if args.what == "record":
        return record(args.dir, args.real, args.pure)
    return compare(args.old, args.new)


if __name__ == "__main__":
    raise SystemExit(main())
