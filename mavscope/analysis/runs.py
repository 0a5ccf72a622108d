"""Runs of consecutive integers, the one way the analyses sum up lists of numbers (missing items, packets)."""

from __future__ import annotations

from collections.abc import Iterable


def runs(numbers: Iterable[int]) -> list[list[int]]:
    """[[first, last], ...] of the runs of consecutive integers in sorted `numbers`."""
    out: list[list[int]] = []
    for n in numbers:
        if out and out[-1][1] == n - 1:
            out[-1][1] = n
        else:
            out.append([n, n])
    return out


def missing_runs(present: Iterable[int], count: int) -> list[list[int]]:
    """[[first, last], ...]: the runs of 0..count-1 not in `present`. Worked out from what is present, not
    from every number: a count of 65,535 costs no more than the numbers present."""
    out: list[list[int]] = []
    nxt = 0
    for n in sorted(n for n in present if 0 <= n < count):
        if n > nxt:
            out.append([nxt, n - 1])
        nxt = n + 1
    if nxt < count:
        out.append([nxt, count - 1])
    return out
