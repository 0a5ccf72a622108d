"""The work a call does, counted rather than timed (a test must not depend on how fast the machine is)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any


def lines_run(fn: Callable[[], object]) -> int:
    """Python lines `fn` runs, in every function it calls."""
    n = 0

    def trace(frame: Any, event: str, arg: object) -> Any:
        nonlocal n
        n += event == "line"
        return trace

    sys.settrace(trace)
    try:
        fn()
    finally:
        sys.settrace(None)
    return n
