#!/usr/bin/env python3
"""Build mavscope's sample captures, byte for byte the same on every run and machine.

    python scripts/make_captures.py [OUTDIR]        (default: the repository's captures/)

The generator itself is the package `scripts/capgen/` (its docstring says how the captures are built
and why they come out the same everywhere); this file is the command line `make captures` runs.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from capgen.build import make_all
from capgen.constants import DEFAULT_OUTDIR


def main(argv: Sequence[str] | None = None) -> int:
    """Write the captures into OUTDIR (default captures/) and print each one's frame counts."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) > 1 or (args and args[0] in ("-h", "--help")):
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    outdir = Path(args[0]) if args else DEFAULT_OUTDIR
    expected = make_all(outdir)
    for name, e in expected.items():
        print(f"{name:24} {e['frames']:5} frames  ok {e['crc_ok']}  bad {e['crc_bad']}  "
              f"unchecked {e['crc_unchecked']}  truncated {e['truncated']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
