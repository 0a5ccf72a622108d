"""Helpers for the TUI tests: waiting for the index, typing, and a large generated capture."""

from __future__ import annotations

import asyncio
import itertools
import time
from collections.abc import Awaitable, Callable
from pathlib import Path

from mavscope.capture.detect import open_capture
from tests.conftest import CAPTURES
from tests.support.builders import write_pcap

SIZE = (120, 40)


def run(coro: Awaitable[None]) -> None:
    """Run a Pilot scenario (the tests are plain functions: no asyncio plugin needed)."""
    asyncio.run(coro)  # type: ignore[arg-type]


async def wait_for(pilot, cond: Callable[[], bool], timeout: float = 20.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting for the app")
        await pilot.pause(0.02)
    await pilot.pause()


async def ready(pilot) -> None:  # type: ignore[no-untyped-def]
    """Wait until the index is complete and the list shows it."""
    app = pilot.app
    await wait_for(pilot, lambda: app.index.done and app.packet_list.count == len(app.index)
                   and app.tree.detail is not None)


async def open_analysis(pilot, *keys: str) -> None:  # type: ignore[no-untyped-def]
    """Press `keys` (the last opens an analysis screen) and wait until the screen has its result."""
    await pilot.press(*keys)
    await wait_for(pilot, lambda: pilot.app.screen.result is not None)


async def type_text(pilot, text: str) -> None:  # type: ignore[no-untyped-def]
    keys = {" ": "space", "=": "equals_sign", "!": "exclamation_mark", '"': "quotation_mark", ".": "full_stop",
            "/": "slash", "<": "less_than_sign", ">": "greater_than_sign", "(": "left_parenthesis",
            ")": "right_parenthesis", "-": "minus", ":": "colon", "_": "underscore"}
    await pilot.press(*(keys.get(c, c) for c in text))


def write_big_capture(path: Path, frames: int, source: Path = CAPTURES / "px4_sitl_udp.pcap") -> int:
    """A pcap of about `frames` frames: the records of `source` repeated, times shifted. Returns records."""
    with open_capture(source) as r:
        recs = [(rec.time or 0.0, rec.data) for rec in r]  # (the bundled capture's records all have a time)
    t0 = recs[0][0]
    span = recs[-1][0] - t0 + 0.01
    records = ((t + rep * span, data) for rep in itertools.count() for t, data in recs)
    write_pcap(path, itertools.islice(records, frames))
    return frames
