"""`make fuzz`: every target for SECONDS each (default 60), seeds written first, findings in the output."""

from __future__ import annotations

import subprocess
import sys

from tests.fuzz.seeds import ROOT, write
from tests.fuzz.targets import TARGETS


def main() -> int:
    seconds = int(sys.argv[1]) if len(sys.argv) > 1 else 60
    corpus = ROOT / ".cache" / "fuzz"
    write(corpus)
    failed = []
    for name in TARGETS:
        crashes = corpus / "crashes" / name
        crashes.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "tests.fuzz.targets", name, str(corpus / name), f"-max_total_time={seconds}",
               "-rss_limit_mb=2048", "-timeout=30", f"-artifact_prefix={crashes}/", "-print_final_stats=1"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=ROOT, check=False).returncode:
            failed.append(name)
    print("fuzz: " + (f"findings in {', '.join(failed)} (see .cache/fuzz/crashes/)" if failed else "no findings"))
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
