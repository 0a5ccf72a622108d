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
